//! The `snerf` command: subcommands only; the work lives in the crates.

mod bake_cmd;
mod bench;
mod cli;
mod demo;
mod stream_cmd;
mod stylize_cmd;
mod view_cmd;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::dispatch(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

//! The `snerf` command: subcommands only; the work lives in the crates.

mod args;
mod bake_cmd;
mod bench;
mod capture_cmd;
mod cli;
mod demo;
mod report_cmd;
mod scene_cmd;
mod stream_cmd;
mod stylize_cmd;
mod train_cmd;
mod view_cmd;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = match cli::Cli::try_parse() {
        Ok(a) => a,
        Err(e) => {
            // A refused command line under --json is a JSON error on stdout too (help and
            // --version are not errors).
            let help = matches!(e.kind(), clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion);
            if !help && std::env::args().any(|a| a == "--json") {
                let v = serde_json::json!({ "command": null, "error": e.render().to_string().trim(), "interrupted": false });
                println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
            }
            e.exit();
        }
    };
    let json = args.json;
    let command = cli::command_name(&args.cmd);
    // The server shuts down on its own Ctrl-C handling; every other command saves (long
    // jobs) or cleans its temp files (the rest) on Ctrl-C and SIGTERM.
    if !matches!(args.cmd, cli::Cmd::Serve(_)) {
        snerf_files::interrupt::install();
    }
    match cli::dispatch(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            let interrupted = snerf_files::interrupt::is_interrupted(&e);
            if json {
                // --json callers read stdout: an error is a JSON object too.
                let v = serde_json::json!({ "command": command, "error": format!("{e:#}"), "interrupted": interrupted });
                println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
            }
            if interrupted {
                ExitCode::from(snerf_files::interrupt::EXIT_INTERRUPTED)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

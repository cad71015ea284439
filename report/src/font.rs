//! The one font the plots use, compiled into the binary: a headless machine (a CI runner, a
//! training server) has no fonts to find, and plots without labels are no use.
//!
//! `fonts/DejaVuSans-subset.ttf` is DejaVu Sans reduced to Latin, Greek and the punctuation
//! the report writes (45 KB instead of 740 KB); its licence is `fonts/LICENSE-DejaVu.txt`.

use std::sync::Once;

pub const FAMILY: &str = "sans-serif";
pub static TTF: &[u8] = include_bytes!("../fonts/DejaVuSans-subset.ttf");

/// Register the font with plotters (once per process; later calls do nothing).
pub fn register() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for style in [plotters::style::FontStyle::Normal, plotters::style::FontStyle::Bold] {
            // The font is a fixed, valid file checked by the tests: failure is a build defect.
            plotters::style::register_font(FAMILY, style, TTF).unwrap_or_else(|_| panic!("the embedded font does not parse"));
        }
    });
}

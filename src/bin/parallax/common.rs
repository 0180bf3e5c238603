//! Plumbing every subcommand shares: `--report`, `--quiet`, progress bars.

use std::path::PathBuf;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use parallax::trace::Trace;

/// Flags every subcommand takes.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct CommonArgs {
    /// Write the trace of this run as JSON (stages, times, warnings, peak memory) to FILE.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// No progress bars or informational output on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

impl CommonArgs {
    /// Writes the report when `--report` was given, and prints the trace's warnings unless quiet.
    pub fn finish(&self, trace: &Trace) -> parallax::Result<()> {
        self.print_warnings(trace);
        if let Some(path) = &self.report {
            std::fs::write(path, trace.report().to_json())
                .map_err(|e| parallax::Error::io(path, e))?;
        }
        Ok(())
    }

    /// `result`, with the warnings gathered so far printed first when it is an error: they
    /// often say why it failed (a flat pair's "nothing to match" before "no valid depth").
    pub fn or_warnings<T>(
        &self,
        trace: &Trace,
        result: parallax::Result<T>,
    ) -> parallax::Result<T> {
        if result.is_err() {
            self.print_warnings(trace);
        }
        result
    }

    fn print_warnings(&self, trace: &Trace) {
        if self.quiet {
            return;
        }
        // A warning repeated by several stages of one run (each call that reuses a product
        // reports its warnings again) is printed once.
        let mut seen = std::collections::HashSet::new();
        for w in trace.warnings().iter().filter(|w| seen.insert(w.as_str())) {
            eprintln!("parallax: warning: {w}");
        }
    }

    /// A spinner with a message on stderr; hidden when quiet or when stderr is not a terminal.
    pub fn spinner(&self, message: &str) -> ProgressBar {
        let bar = if self.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
        };
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_message(message.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        bar
    }

    /// A progress bar of `len` steps (for subcommands with countable work) on stderr; hidden when quiet or when stderr is not a terminal.
    #[allow(dead_code)] // used by the subcommands of the stage issues
    pub fn progress(&self, len: u64, message: &str) -> ProgressBar {
        let bar = if self.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr())
        };
        bar.set_style(
            ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} [{elapsed}<{eta}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_message(message.to_string());
        bar
    }
}

/// `base` with the fields of `--options` over it: inline JSON or `@FILE` (see
/// `StereoOptions::with_json`).
pub fn stereo_options(
    base: &parallax::stereo::StereoOptions,
    spec: &str,
) -> parallax::Result<parallax::stereo::StereoOptions> {
    base.with_json(&options_text(spec)?)
}

/// The JSON of an `--options` spec: the spec itself, or the file named after `@`.
pub fn options_text(spec: &str) -> parallax::Result<String> {
    match spec.strip_prefix('@') {
        Some(path) => std::fs::read_to_string(path).map_err(|e| parallax::Error::io(path, e)),
        None => Ok(spec.to_string()),
    }
}

/// `X,Y,Z`: three finite numbers (a clap value parser).
pub fn parse_vec3(text: &str) -> std::result::Result<[f32; 3], String> {
    let values: Vec<f32> = text
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|e| format!("{v:?}: {e}")))
        .collect::<std::result::Result<_, _>>()?;
    match values[..] {
        [x, y, z] if values.iter().all(|v| v.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("expected three finite numbers X,Y,Z, got {text:?}")),
    }
}

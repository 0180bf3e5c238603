//! What a call did: every product computed, reused or skipped, with its time and why; and the JSON
//! report (`--report FILE.json`, `plx_scene_report`) that tools and benchmarks read.
//!
//! The report is a stable interface. Its shape:
//! ```json
//! {
//!   "version": "0.1.0",
//!   "stages": [ {"name": "stereo", "status": "computed", "ms": 12.5, "why": "stereo pair changed"} ],
//!   "warnings": ["…"],
//!   "peak_rss_mb": 123.4,
//!   "total_ms": 20.1
//! }
//! ```
//! `stages` are in the order they finished (a product after the products it needs; sub-stages such
//! as `stereo.cost` right after their stage); `status` is one of `computed`, `reused`, `skipped`;
//! `ms` is wall-clock milliseconds (0 for reused and skipped); `peak_rss_mb` is the process's peak
//! resident memory in MiB where the OS reports it (Linux), else `null`.

use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A host's view into calls while they run: progress with cancellation, and every record and
/// warning as it is added (for a log). A [`crate::scene::Scene`] hands its observer to the trace
/// of each call ([`Trace::set_observer`]).
///
/// Methods are called on the thread that made the call, in the order things happen. They must not
/// call back into the scene being traced (it is busy).
pub trait TraceObserver: Send + Sync {
    /// A product starts being computed (`fraction` 0) or has been computed (`fraction` 1).
    /// Return `false` to cancel the call: it then fails with [`Error::Cancelled`] before that
    /// product (at 0) or right after it, keeping it cached (at 1).
    fn progress(&self, stage: &str, fraction: f32) -> bool {
        let _ = (stage, fraction);
        true
    }

    /// A record was added (a product computed, reused or skipped).
    fn record(&self, record: &StageRecord) {
        let _ = record;
    }

    /// A warning was added.
    fn warning(&self, message: &str) {
        let _ = message;
    }
}

/// A shared [`TraceObserver`].
#[derive(Clone)]
pub struct Observer(pub Arc<dyn TraceObserver>);

impl std::fmt::Debug for Observer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Observer(..)")
    }
}

/// What happened to one product during a call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StageStatus {
    /// Computed in this call.
    Computed,
    /// Taken from the cache: none of its inputs changed.
    Reused,
    /// Not needed by what was asked for.
    Skipped,
}

/// One line of the trace.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageRecord {
    /// Product or sub-stage name, e.g. `stereo` or `stereo.aggregate`.
    pub name: String,
    /// Computed, reused or skipped.
    pub status: StageStatus,
    /// Wall-clock time in milliseconds (0 unless computed).
    pub ms: f64,
    /// Why: which input changed, or why it was not needed.
    pub why: String,
}

/// The record of one call into a [`crate::scene::Scene`] (or one CLI command).
#[derive(Debug, Clone, Default)]
pub struct Trace {
    stages: Vec<StageRecord>,
    warnings: Vec<String>,
    started: Option<Instant>,
    /// Total time and peak memory, frozen by [`Trace::finish`] so the report of a past call does
    /// not change when read twice.
    finished: Option<(f64, Option<f64>)>,
    observer: Option<Observer>,
}

impl Trace {
    /// An empty trace whose clock starts now.
    pub fn new() -> Self {
        Trace {
            stages: Vec::new(),
            warnings: Vec::new(),
            started: Some(Instant::now()),
            finished: None,
            observer: None,
        }
    }

    /// Sends this trace's progress, records and warnings to `observer` from now on.
    pub fn set_observer(&mut self, observer: Option<Observer>) {
        self.observer = observer;
    }

    /// Tells the observer that `stage` is at `fraction` (0 = starting, 1 = done).
    ///
    /// # Errors
    /// `Cancelled` when the observer asks to stop.
    pub fn progress(&self, stage: &str, fraction: f32) -> Result<()> {
        match &self.observer {
            Some(o) if !o.0.progress(stage, fraction) => {
                Err(Error::Cancelled(if fraction <= 0.0 {
                    format!("the progress callback stopped the call before `{stage}`")
                } else {
                    format!("the progress callback stopped the call after `{stage}` (kept)")
                }))
            }
            _ => Ok(()),
        }
    }

    /// Ends the call: freezes its total time and the peak memory seen so far.
    pub fn finish(&mut self) {
        self.finished = Some((self.elapsed_ms(), peak_rss_mb()));
    }

    fn elapsed_ms(&self) -> f64 {
        self.started
            .map(|s| s.elapsed().as_secs_f64() * 1e3)
            .unwrap_or(0.0)
    }

    /// Adds a record.
    pub fn record(
        &mut self,
        name: impl Into<String>,
        status: StageStatus,
        ms: f64,
        why: impl Into<String>,
    ) {
        let record = StageRecord {
            name: name.into(),
            status,
            ms,
            why: why.into(),
        };
        if let Some(o) = &self.observer {
            o.0.record(&record);
        }
        self.stages.push(record);
    }

    /// Records the timed parts of `stage` (name, milliseconds) as computed, "part of `stage`",
    /// when the last record is `stage` computed; a reused stage did no work, so it has no parts.
    pub fn record_parts(&mut self, stage: &str, parts: &[(String, f64)]) {
        if self
            .stages
            .last()
            .is_some_and(|s| s.name == stage && s.status == StageStatus::Computed)
        {
            for (name, ms) in parts {
                self.record(
                    name.clone(),
                    StageStatus::Computed,
                    *ms,
                    format!("part of {stage}"),
                );
            }
        }
    }

    /// Runs `f`, records it as computed with its time, and returns its value.
    pub fn time<T>(&mut self, name: &str, why: &str, f: impl FnOnce(&mut Trace) -> T) -> T {
        let start = Instant::now();
        let value = f(self);
        self.record(
            name,
            StageStatus::Computed,
            start.elapsed().as_secs_f64() * 1e3,
            why,
        );
        value
    }

    /// Adds a warning (a repaired input, a fallback taken, …), unless this trace holds it already:
    /// a call that reaches a product twice (the lighting, through the lights and then the
    /// environment) warns about it once, and the observer hears it once.
    pub fn warn(&mut self, message: impl Into<String>) {
        let message = message.into();
        if self.warnings.contains(&message) {
            return;
        }
        if let Some(o) = &self.observer {
            o.0.warning(&message);
        }
        self.warnings.push(message);
    }

    /// Records so far.
    pub fn stages(&self) -> &[StageRecord] {
        &self.stages
    }

    /// Warnings so far.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The first record with this name, if any.
    pub fn stage(&self, name: &str) -> Option<&StageRecord> {
        self.stages.iter().find(|s| s.name == name)
    }

    /// Appends another trace's records, and those of its warnings this trace does not hold yet
    /// (see [`Trace::warn`]): a host (or the CLI) that merges the traces of several calls gets
    /// each warning once, where every call that reuses a product warns about it again (the
    /// lighting's fallback, say).
    pub fn extend(&mut self, other: Trace) {
        self.stages.extend(other.stages);
        for warning in other.warnings {
            if !self.warnings.contains(&warning) {
                self.warnings.push(warning);
            }
        }
    }

    /// The report of this trace (see the module documentation for its shape).
    pub fn report(&self) -> Report {
        let (total_ms, peak_rss_mb) = self
            .finished
            .unwrap_or_else(|| (self.elapsed_ms(), peak_rss_mb()));
        Report {
            version: crate::VERSION.to_string(),
            stages: self.stages.clone(),
            warnings: self.warnings.clone(),
            peak_rss_mb,
            total_ms,
        }
    }
}

/// Runs `f` and appends its wall-clock time to `parts` as `name`, in milliseconds: how a stage
/// times its own parts for [`Trace::record_parts`] (the matcher's `StereoStats::timings`, the
/// lighting estimate's `timings`).
pub(crate) fn time_part<T>(parts: &mut Vec<(String, f64)>, name: &str, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let value = f();
    parts.push((name.to_string(), start.elapsed().as_secs_f64() * 1e3));
    value
}

/// The JSON report of a call (see the module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// Parallax version that wrote it.
    pub version: String,
    /// Every stage in the order it finished.
    pub stages: Vec<StageRecord>,
    /// Warnings raised.
    pub warnings: Vec<String>,
    /// Peak resident memory of the process in MiB, when the OS reports it.
    pub peak_rss_mb: Option<f64>,
    /// Wall-clock time of the whole call in milliseconds.
    pub total_ms: f64,
}

impl Report {
    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        // Serialising plain structs of strings and finite numbers cannot fail; NaN would become null.
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

/// Peak resident set size of this process in MiB (Linux `VmHWM`), or `None` where unknown.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_has_the_documented_shape() {
        let mut t = Trace::new();
        let v = t.time("stereo", "stereo pair changed", |t| {
            t.record("stereo.cost", StageStatus::Computed, 1.0, "");
            42
        });
        assert_eq!(v, 42);
        t.record("mesh", StageStatus::Skipped, 0.0, "not asked for");
        t.warn("fell back");
        let json: serde_json::Value = serde_json::from_str(&t.report().to_json()).unwrap();
        assert_eq!(json["version"], crate::VERSION);
        let stages = json["stages"].as_array().unwrap();
        assert_eq!(stages[0]["name"], "stereo.cost");
        assert_eq!(stages[1]["name"], "stereo");
        assert_eq!(stages[1]["status"], "computed");
        assert_eq!(stages[2]["status"], "skipped");
        assert!(stages[1]["ms"].as_f64().unwrap() >= 0.0);
        assert_eq!(json["warnings"][0], "fell back");
        assert!(json["total_ms"].as_f64().unwrap() >= 0.0);
        if cfg!(target_os = "linux") {
            assert!(json["peak_rss_mb"].as_f64().unwrap() > 0.0);
        }
    }

    #[test]
    fn merged_traces_hold_each_warning_once() {
        let call = |warnings: &[&str]| {
            let mut t = Trace::new();
            t.record("lighting", StageStatus::Reused, 0.0, "");
            for w in warnings {
                t.warn(*w);
            }
            t
        };
        let mut once = Trace::new();
        once.warn("fallback");
        once.warn("fallback");
        assert_eq!(once.warnings(), ["fallback"]);

        let mut merged = Trace::new();
        merged.extend(call(&["fallback"]));
        merged.extend(call(&["fallback", "no surfaces"]));
        merged.extend(call(&["fallback"]));
        assert_eq!(merged.warnings(), ["fallback", "no surfaces"]);
        assert_eq!(merged.stages().len(), 3);
    }

    #[test]
    fn a_finished_trace_reports_the_same_every_time() {
        let mut t = Trace::new();
        t.finish();
        let first = t.report().to_json();
        std::thread::sleep(std::time::Duration::from_millis(5));
        assert_eq!(first, t.report().to_json());
    }
}

//! A 4000×3000 pair with 64 disparities and the fast preset: finite output, and the matcher's
//! memory within 2 bytes per (pixel × disparity) + 64 MB, measured as the process's peak resident
//! memory (this test runs in its own process) and as the matcher's own account; and the same
//! bound for a kept `StereoMatcher` on its second match, whose buffers are reused.

use parallax::image::{Image, PixelFormat};
use parallax::stereo::{match_pair, Preset, StereoMatcher, StereoOptions};

fn rss_mb(key: &str) -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

#[test]
fn twelve_megapixels_fit_the_memory_bound() {
    let (w, h) = (4000usize, 3000usize);
    // A texture shifted by 10 px, built without floating point for speed.
    let tex = |x: usize, y: usize| -> u8 {
        let v = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(40_503);
        ((v >> 13) ^ (v >> 7)) as u8
    };
    let left: Vec<u8> = (0..w * h).map(|p| tex(p % w, p / w)).collect();
    let right: Vec<u8> = (0..w * h).map(|p| tex(p % w + 10, p / w)).collect();
    let left = Image::from_bytes(w as u32, h as u32, PixelFormat::Gray8, left).unwrap();
    let right = Image::from_bytes(w as u32, h as u32, PixelFormat::Gray8, right).unwrap();
    let inputs_mb = rss_mb("VmRSS:");
    let options = StereoOptions {
        max_disparity: 64,
        ..StereoOptions::preset(Preset::Fast)
    };
    let d = match_pair(&left.view(), &right.view(), &options).unwrap();
    let peak_mb = rss_mb("VmHWM:");
    assert!(d.disparity.pixels().iter().all(|v| v.is_finite()));
    let bound_mb = (2.0 * (w * h) as f64 * 65.0) / (1024.0 * 1024.0) + 64.0;
    let own_mb = d.stats.peak_working_bytes as f64 / (1024.0 * 1024.0);
    eprintln!(
        "4000x3000, 65 disparities, fast: {:.0} ms; matcher's own peak {own_mb:.0} MB; process peak {peak_mb:.0} MB, of which inputs {inputs_mb:.0} MB; bound {bound_mb:.0} MB",
        d.stats.total_ms
    );
    assert!(
        own_mb <= bound_mb,
        "matcher's own peak {own_mb:.0} MB > {bound_mb:.0} MB"
    );
    // Process peak less what the test itself holds (the two input images and the outputs).
    let outputs_mb = (w * h * 8) as f64 / (1024.0 * 1024.0);
    assert!(
        peak_mb - inputs_mb - outputs_mb <= bound_mb,
        "process peak {peak_mb:.0} MB − inputs {inputs_mb:.0} MB − outputs {outputs_mb:.0} MB > {bound_mb:.0} MB"
    );
    // Most pixels are right (the shift is 10 everywhere).
    let right_px = d
        .disparity
        .pixels()
        .iter()
        .filter(|v| (**v - 10.0).abs() < 1.0)
        .count();
    assert!(right_px as f64 > 0.9 * (w * h) as f64, "{right_px}");
    drop(d);

    // A kept matcher: its second match reuses the first one's buffers. The peak is measured
    // from the second match on (writing 5 to clear_refs resets it to the current resident size).
    let mut matcher = StereoMatcher::new();
    matcher
        .match_pair(&left.view(), &right.view(), &options)
        .unwrap();
    let retained_mb = matcher.retained_bytes() as f64 / (1024.0 * 1024.0);
    if std::fs::write("/proc/self/clear_refs", "5").is_ok() {
        let d = matcher
            .match_pair(&left.view(), &right.view(), &options)
            .unwrap();
        let peak_mb = rss_mb("VmHWM:");
        eprintln!(
            "kept matcher, second match: {:.0} ms; holds {retained_mb:.0} MB between matches; process peak {peak_mb:.0} MB",
            d.stats.total_ms
        );
        assert!(
            peak_mb - inputs_mb - outputs_mb <= bound_mb,
            "kept matcher: process peak {peak_mb:.0} MB − inputs {inputs_mb:.0} MB − outputs {outputs_mb:.0} MB > {bound_mb:.0} MB"
        );
    }
}

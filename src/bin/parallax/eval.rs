//! `parallax eval stereo`: scores the matcher (and, with `--peer opencv`, OpenCV's StereoSGBM in
//! the same run) on Middlebury scene folders with Middlebury's rules, and writes an
//! error-against-run-time table (Markdown) and plot (PNG).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use parallax::camera::StereoCalibration;
use parallax::image::{Image, ImageLimits, PixelFormat, Raster};
use parallax::stereo::metrics::{score, Scores};
use parallax::stereo::{self, Aggregation, Preset, StereoOptions};
use parallax::trace::{StageStatus, Trace};
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::plot::{scatter, Axes, Point};

#[cfg(all(feature = "gpu", feature = "gltf"))]
#[path = "eval_composite.rs"]
mod composite;
#[path = "eval_lights.rs"]
mod lights;
#[path = "eval_reconstruction.rs"]
mod reconstruction;

/// Arguments of `parallax eval`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Subcommand, Debug)]
enum What {
    /// Stereo matching against Middlebury ground truth.
    Stereo(StereoArgs),
    /// Depth, mesh, normals, planes, up and placement against synthetic scenes' exact truth.
    Reconstruction(reconstruction::ReconstructionArgs),
    /// Shadow mask, lights, environment and SH against synthetic scenes' exact truth.
    Lights(lights::LightsArgs),
    /// The composite (stereo → mesh → lights → render, and with TRUE depth and lights) against
    /// the path tracer's ground truth, for every shading and shadow mode, with run times.
    #[cfg(all(feature = "gpu", feature = "gltf"))]
    Composite(composite::CompositeArgs),
}

/// Arguments of `parallax eval stereo`.
#[derive(clap::Args, Debug)]
pub struct StereoArgs {
    /// Folder of scene folders (im0.png, im1.png, calib.txt, disp0GT.pfm, mask0nocc.png).
    #[arg(long, value_name = "DIR")]
    data: PathBuf,
    /// Preset to score, or `all` for every preset and every method (SAD+DP, SGM 4/8 paths,
    /// with and without coarse-to-fine).
    #[arg(long, default_value = "balanced", value_name = "P|all")]
    preset: String,
    /// Also run a peer on the same pairs: `opencv` (StereoSGBM 3-way and HH4, from a Python
    /// virtual environment created on first use under ~/.cache/parallax), on each pair right
    /// after our own matches of it.
    #[arg(long, value_name = "PEER")]
    peer: Option<String>,
    /// Where the tables, plot and peer outputs go.
    #[arg(long, default_value = "target/eval-stereo", value_name = "DIR")]
    out_dir: PathBuf,
    /// Match each pair this many times and report the median time (and per-stage medians), for
    /// a loaded machine; the peer's time is the median of as many `compute()` calls.
    #[arg(long, default_value_t = 1, value_name = "N")]
    repeat: u32,
    /// Match every time with a fresh matcher (`stereo::match_pair`: working memory allocated,
    /// and zeroed by the kernel, for each match) instead of one `StereoMatcher` kept for the whole
    /// run, as a host matching a stream of frames keeps one.
    #[arg(long)]
    cold: bool,
    /// Also score these options: a JSON object of `StereoOptions` fields (inline, or `@FILE`),
    /// every field left out taken from the `balanced` preset, `max_disparity` from each scene
    /// (for example `{"smoothing_passes": 2, "p2": 400}`). May be given several times.
    #[arg(long, value_name = "JSON|@FILE")]
    options: Vec<String>,
    #[command(flatten)]
    common: CommonArgs,
}

/// Dispatches `parallax eval …`.
pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Stereo(a) => run_stereo(a),
        What::Reconstruction(a) => reconstruction::run(a),
        What::Lights(a) => lights::run(a),
        #[cfg(all(feature = "gpu", feature = "gltf"))]
        What::Composite(a) => composite::run(a),
    }
}

struct Scene {
    name: String,
    dir: PathBuf,
    left: Image,
    right: Image,
    calib: StereoCalibration,
    truth: Raster<f32>,
    mask: Raster<u8>,
}

/// One scored configuration: per-scene scores and matching times.
struct Row {
    name: String,
    description: String,
    scores: Vec<Scores>,
    ms: Vec<f64>,
    peer: bool,
}

fn load_scenes(dir: &Path) -> Result<Vec<Scene>> {
    let limits = ImageLimits::default();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("im0.png").is_file() && p.join("disp0GT.pfm").is_file())
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        return Err(Error::invalid(format!(
            "{}: no scene folders (each needs im0.png, im1.png, calib.txt, disp0GT.pfm, mask0nocc.png)",
            dir.display()
        )));
    }
    dirs.into_iter()
        .map(|d| {
            let mask_img = Image::load(d.join("mask0nocc.png"), &limits)?;
            let bpp = mask_img.format().bytes_per_pixel();
            if !mask_img.format().is_srgb8() {
                return Err(Error::format(format!(
                    "{}: mask0nocc.png must be 8-bit",
                    d.display()
                )));
            }
            let mask = Raster::from_vec(
                mask_img.width() as usize,
                mask_img.height() as usize,
                mask_img
                    .as_bytes()
                    .chunks_exact(bpp)
                    .map(|p| p[0])
                    .collect(),
            );
            let _ = PixelFormat::Gray8;
            Ok(Scene {
                name: d
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                left: Image::load(d.join("im0.png"), &limits)?,
                right: Image::load(d.join("im1.png"), &limits)?,
                calib: StereoCalibration::load_middlebury(d.join("calib.txt"))?,
                truth: Raster::read_pfm(d.join("disp0GT.pfm"), &limits)?,
                mask,
                dir: d,
            })
        })
        .collect()
}

fn ndisp(scene: &Scene) -> u32 {
    scene.calib.max_disparity.unwrap_or(64)
}

fn configurations(preset: &str) -> Result<Vec<(String, String, StereoOptions)>> {
    let describe = |o: &StereoOptions| {
        format!(
            "{:?} {}×{}, {:?}{}",
            o.cost,
            2 * o.census_radius.0 + 1,
            2 * o.census_radius.1 + 1,
            o.aggregation,
            if o.coarse_levels > 0 {
                ", coarse-to-fine"
            } else {
                ""
            }
        )
    };
    if preset != "all" {
        let p: Preset = preset.parse()?;
        let o = StereoOptions::preset(p);
        return Ok(vec![(p.to_string(), describe(&o), o)]);
    }
    let mut list: Vec<(String, String, StereoOptions)> = Preset::ALL
        .iter()
        .map(|&p| {
            let o = StereoOptions::preset(p);
            (p.to_string(), describe(&o), o)
        })
        .collect();
    let b = StereoOptions::default();
    let thesis = StereoOptions::thesis();
    list.push((
        "sad+dp (thesis)".into(),
        format!(
            "SAD {}×{} blocks, scanline DP",
            2 * thesis.sad_radius + 1,
            2 * thesis.sad_radius + 1
        ),
        thesis,
    ));
    // `balanced` is census + 4-path SGM + coarse-to-fine (`quality` 8 paths over the full search
    // with a wider census and the local fit); the other combinations of paths and search.
    for (name, o) in [
        (
            "census+sgm8",
            StereoOptions {
                aggregation: Aggregation::Sgm8,
                coarse_levels: 0,
                ..b.clone()
            },
        ),
        (
            "census+sgm4",
            StereoOptions {
                coarse_levels: 0,
                ..b.clone()
            },
        ),
        (
            "census+sgm8+c2f",
            StereoOptions {
                aggregation: Aggregation::Sgm8,
                ..b.clone()
            },
        ),
    ] {
        list.push((name.to_string(), describe(&o), o));
    }
    Ok(list)
}

fn run_stereo(args: StereoArgs) -> Result<()> {
    let mut trace = Trace::new();
    let scenes = trace.time("load", "scene folders", |_| load_scenes(&args.data))?;
    std::fs::create_dir_all(&args.out_dir).map_err(|e| Error::io(&args.out_dir, e))?;
    let mut configs = configurations(&args.preset)?;
    for spec in &args.options {
        let o = crate::common::stereo_options(&StereoOptions::default(), spec)?;
        o.validate(u32::MAX)?;
        configs.push((format!("options {spec}"), "from --options".into(), o));
    }
    let peer = match args.peer.as_deref() {
        None => None,
        Some("opencv") => Some(OpenCvPeer::prepare(args.common.quiet)?),
        Some(other) => {
            return Err(Error::invalid(format!(
                "unknown peer {other:?} (expected opencv)"
            )))
        }
    };
    let mut kept = stereo::StereoMatcher::new();
    let mut match_pair = |s: &Scene, o: &StereoOptions| {
        if args.cold {
            stereo::match_pair(&s.left.view(), &s.right.view(), o)
        } else {
            kept.match_pair(&s.left.view(), &s.right.view(), o)
        }
    };
    // Warm up (page faults, thread pool, the kept matcher's buffers) on the largest search, so
    // that no timed pair is the first of its size.
    let largest = scenes
        .iter()
        .max_by_key(|s| s.left.width() as u64 * s.left.height() as u64 * ndisp(s) as u64);
    if let Some(s) = largest {
        let o = StereoOptions {
            max_disparity: ndisp(s) - 1,
            ..StereoOptions::default()
        };
        match_pair(s, &o)?;
    }
    let bar = args
        .common
        .progress((configs.len() * scenes.len()) as u64, "matching");
    let mut rows: Vec<Row> = configs
        .iter()
        .map(|(name, description, _)| Row {
            name: name.clone(),
            description: description.clone(),
            scores: vec![],
            ms: vec![],
            peer: false,
        })
        .collect();
    let mut stages: Vec<Vec<(String, f64)>> = vec![Vec::new(); configs.len()];
    let mut peer_rows: Vec<Row> = Vec::new();
    // Scene by scene, the peer right after our matches of the same pair, so that both are timed
    // in the same minute of a machine whose speed drifts.
    for s in &scenes {
        for (c, (name, _, base)) in configs.iter().enumerate() {
            let o = StereoOptions {
                max_disparity: ndisp(s).saturating_sub(1).max(1),
                ..base.clone()
            };
            let mut runs = Vec::new();
            for _ in 0..args.repeat.max(1) {
                runs.push(match_pair(s, &o)?);
            }
            let median = |mut v: Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            };
            let total = median(runs.iter().map(|d| d.stats.total_ms).collect());
            let d = &runs[0];
            rows[c]
                .scores
                .push(score(&d.disparity, &s.truth, &s.mask, ndisp(s) as f32)?);
            rows[c].ms.push(total);
            for (stage, _) in &d.stats.timings {
                let ms = median(
                    runs.iter()
                        .map(|r| {
                            r.stats
                                .timings
                                .iter()
                                .find(|(n, _)| n == stage)
                                .map_or(0.0, |t| t.1)
                        })
                        .collect(),
                );
                match stages[c].iter_mut().find(|(n, _)| n == stage) {
                    Some(e) => e.1 += ms,
                    None => stages[c].push((stage.clone(), ms)),
                }
            }
            trace.record(
                format!("stereo[{name}/{}]", s.name),
                StageStatus::Computed,
                total,
                "eval",
            );
            bar.inc(1);
        }
        if let Some(peer) = &peer {
            let scene_rows =
                trace.time(&format!("peer.opencv[{}]", s.name), "--peer opencv", |_| {
                    peer.run(std::slice::from_ref(s), &args.out_dir, args.repeat)
                })?;
            for r in scene_rows {
                match peer_rows.iter_mut().find(|p| p.name == r.name) {
                    Some(p) => {
                        p.scores.extend(r.scores);
                        p.ms.extend(r.ms);
                    }
                    None => peer_rows.push(r),
                }
            }
        }
    }
    bar.finish_and_clear();
    if !args.common.quiet {
        for ((name, _, _), stages) in configs.iter().zip(&stages) {
            let list: Vec<String> = stages
                .iter()
                .map(|(n, ms)| format!("{n} {ms:.0} ms"))
                .collect();
            eprintln!(
                "parallax: {name}: stages over all pairs: {}",
                list.join(", ")
            );
        }
    }
    rows.extend(peer_rows);

    let report = render_report(&rows, &scenes);
    print!("{}", report.summary);
    let md = args.out_dir.join("stereo_eval.md");
    std::fs::write(
        &md,
        format!(
            "{}\n{}\n{}",
            report.summary, report.per_scene, report.legend
        ),
    )
    .map_err(|e| Error::io(&md, e))?;
    let png = args.out_dir.join("stereo_error_vs_time.png");
    plot(&rows, &scenes)?.save_png(&png)?;
    let table = args.out_dir.join("stereo_error_vs_time.md");
    std::fs::write(&table, &report.error_vs_time).map_err(|e| Error::io(&table, e))?;
    if !args.common.quiet {
        eprintln!(
            "parallax: wrote {}, {} and {}",
            md.display(),
            table.display(),
            png.display()
        );
    }
    args.common.finish(&trace)
}

/// Creates (once) a virtual environment with OpenCV and runs `scripts/opencv_sgbm.py` in it.
/// OpenCV's StereoSGBM as the peer: a Python virtual environment with opencv-python-headless
/// (made on first use) and the script that runs it.
struct OpenCvPeer {
    python: PathBuf,
    script: PathBuf,
}

fn peer_error(what: &str, detail: String) -> Error {
    Error::NotAvailable(format!("OpenCV peer: {what}: {detail}"))
}

/// Runs `cmd`; its output, or an error with its stderr.
fn run_command(cmd: &mut Command, what: &str) -> Result<std::process::Output> {
    let out = cmd.output().map_err(|e| peer_error(what, e.to_string()))?;
    if !out.status.success() {
        return Err(peer_error(
            what,
            String::from_utf8_lossy(&out.stderr).trim().to_string(),
        ));
    }
    Ok(out)
}

impl OpenCvPeer {
    /// The environment under the user's cache folder (created when missing) and the script
    /// written next to it; once per run, before anything is timed.
    fn prepare(quiet: bool) -> Result<Self> {
        let cache = std::env::var_os("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
            .unwrap_or_else(|| PathBuf::from("target"))
            .join("parallax");
        let venv = cache.join("opencv-venv");
        let python = venv.join("bin").join("python");
        if !python.is_file() {
            if !quiet {
                eprintln!(
                    "parallax: creating {} with opencv-python-headless (first use only)",
                    venv.display()
                );
            }
            std::fs::create_dir_all(&cache).map_err(|e| Error::io(&cache, e))?;
            run_command(
                Command::new("python3").args(["-m", "venv"]).arg(&venv),
                "python3 -m venv",
            )?;
            run_command(
                Command::new(&python).args([
                    "-m",
                    "pip",
                    "install",
                    "--quiet",
                    "opencv-python-headless",
                    "numpy",
                ]),
                "pip install opencv-python-headless numpy",
            )?;
        }
        let script = cache.join("opencv_sgbm.py");
        std::fs::write(&script, include_str!("../../../scripts/opencv_sgbm.py"))
            .map_err(|e| Error::io(&script, e))?;
        Ok(OpenCvPeer { python, script })
    }

    /// StereoSGBM's rows (3-way and HH4) on `scenes`, each time the median of `repeat` calls.
    fn run(&self, scenes: &[Scene], out_dir: &Path, repeat: u32) -> Result<Vec<Row>> {
        let peer_dir = out_dir.join("opencv");
        let out = run_command(
            Command::new(&self.python)
                .arg(&self.script)
                .args(["--repeat", &repeat.max(1).to_string()])
                .arg(&peer_dir)
                .args(scenes.iter().map(|s| s.dir.as_os_str())),
            "running opencv_sgbm.py",
        )?;
        let mut rows: Vec<Row> = Vec::new();
        // The script's first line names the OpenCV release.
        let mut version = String::from("version unknown");
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            let v: serde_json::Value = serde_json::from_str(line)
                .map_err(|e| peer_error("bad output line", format!("{line}: {e}")))?;
            if let Some(v) = v["opencv"].as_str() {
                version = v.to_string();
                continue;
            }
            let (Some(scene), Some(mode), Some(ms), Some(pfm)) = (
                v["scene"].as_str(),
                v["mode"].as_str(),
                v["ms"].as_f64(),
                v["pfm"].as_str(),
            ) else {
                return Err(peer_error("bad output line", line.to_string()));
            };
            let s = scenes
                .iter()
                .find(|s| s.name == scene)
                .ok_or_else(|| peer_error("unknown scene", scene.to_string()))?;
            let disparity = Raster::read_pfm(pfm, &ImageLimits::default())?;
            let name = format!("opencv {mode}");
            let idx = match rows.iter().position(|r| r.name == name) {
                Some(i) => i,
                None => {
                    rows.push(Row {
                        name: name.clone(),
                        description: format!(
                            "StereoSGBM MODE_{mode} (OpenCV {version}), README parameters"
                        ),
                        scores: vec![],
                        ms: vec![],
                        peer: true,
                    });
                    rows.len() - 1
                }
            };
            rows[idx]
                .scores
                .push(score(&disparity, &s.truth, &s.mask, ndisp(s) as f32)?);
            rows[idx].ms.push(ms);
        }
        if rows.iter().any(|r| r.scores.len() != scenes.len()) || rows.is_empty() {
            return Err(peer_error(
                "incomplete output",
                format!("{} rows", rows.len()),
            ));
        }
        Ok(rows)
    }
}

struct Report {
    summary: String,
    per_scene: String,
    error_vs_time: String,
    legend: String,
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

fn render_report(rows: &[Row], scenes: &[Scene]) -> Report {
    let mp: f64 = scenes
        .iter()
        .map(|s| (s.left.width() * s.left.height()) as f64 / 1e6)
        .sum();
    let reference = rows.iter().find(|r| r.name == "opencv SGBM_3WAY");
    let ref_time: Option<f64> = reference.map(|r| r.ms.iter().sum());
    let ref_bad: Option<f64> = reference.map(|r| mean(r.scores.iter().map(|s| s.nonocc.bad[0])));
    let mut summary = format!(
        "Stereo on {} scenes ({:.2} MP in all), mean over scenes, dense scoring (holes are bad)\n\n",
        scenes.len(),
        mp
    );
    summary.push_str("| method | nonocc bad 0.5 | bad 1.0 | bad 2.0 | all bad 0.5 | holes (nonocc) | avgerr (nonocc) | time, all pairs | ms/MP | time ÷ SGBM_3WAY | bad 0.5 ÷ SGBM_3WAY |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    let mut ev = String::from("| method | what | nonocc bad 0.5 (%) | all bad 0.5 (%) | time per pair (ms) | time, all pairs (s) |\n|---|---|---|---|---|---|\n");
    for r in rows {
        let m = |f: &dyn Fn(&Scores) -> f64| mean(r.scores.iter().map(f));
        let total: f64 = r.ms.iter().sum();
        let bad05 = m(&|s| s.nonocc.bad[0]);
        let ratio =
            |a: Option<f64>, b: f64| a.map_or("–".to_string(), |a| format!("{:.2}", b / a));
        let _ = writeln!(
            summary,
            "| {} | {:.1} % | {:.1} % | {:.1} % | {:.1} % | {:.1} % | {:.2} | {:.3} s | {:.0} | {} | {} |",
            r.name,
            bad05,
            m(&|s| s.nonocc.bad[1]),
            m(&|s| s.nonocc.bad[2]),
            m(&|s| s.all.bad[0]),
            m(&|s| s.nonocc.invalid),
            m(&|s| s.nonocc.avgerr),
            total / 1e3,
            total / mp,
            ratio(ref_time, total),
            ratio(ref_bad, bad05),
        );
        let _ = writeln!(
            ev,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.3} |",
            r.name,
            r.description,
            bad05,
            m(&|s| s.all.bad[0]),
            total / r.ms.len().max(1) as f64,
            total / 1e3
        );
    }
    let mut per_scene =
        String::from("\n## Per scene: nonocc bad 0.5 % / matching ms\n\n| method |");
    for s in scenes {
        let _ = write!(per_scene, " {} |", s.name);
    }
    per_scene.push_str("\n|---|");
    per_scene.push_str(&"---|".repeat(scenes.len()));
    per_scene.push('\n');
    for r in rows {
        let _ = write!(per_scene, "| {} |", r.name);
        for (s, ms) in r.scores.iter().zip(&r.ms) {
            let _ = write!(per_scene, " {:.1} / {:.0} |", s.nonocc.bad[0], ms);
        }
        per_scene.push('\n');
    }
    let mut legend = String::from("\n## Plot colours (stereo_error_vs_time.png: x = time per pair, log scale 1 ms – 10 s; y = nonocc bad 0.5 %, 0–100)\n\n");
    for (i, r) in rows.iter().enumerate() {
        let c = colour(i, rows.len(), r.peer);
        let _ = writeln!(
            legend,
            "- {}: rgb({}, {}, {}){}",
            r.name,
            c[0],
            c[1],
            c[2],
            if r.peer {
                " (square outline: peer)"
            } else {
                ""
            }
        );
    }
    ev.push_str(&legend);
    Report {
        summary,
        per_scene,
        error_vs_time: ev,
        legend,
    }
}

fn colour(i: usize, n: usize, peer: bool) -> [u8; 3] {
    if peer {
        return if i.is_multiple_of(2) {
            [0, 0, 0]
        } else {
            [120, 120, 120]
        };
    }
    stereo::preview::jet(if n <= 1 {
        0.0
    } else {
        i as f32 / (n - 1) as f32
    })
}

/// Error against time: x = time per pair on a log scale (1 ms – 10 s), y = nonocc bad 0.5 %.
fn plot(rows: &[Row], _scenes: &[Scene]) -> Result<Image> {
    let n = rows.len();
    let points: Vec<Point> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| Point {
            ms: r.ms.iter().sum::<f64>() / r.ms.len().max(1) as f64,
            error: mean(r.scores.iter().map(|s| s.nonocc.bad[0])),
            colour: colour(i, n, r.peer),
            hollow: r.peer,
        })
        .collect();
    scatter(
        &points,
        &Axes {
            decade_lo: 0,
            decade_hi: 4,
            error_max: 100.0,
        },
    )
}

//! `parallax eval composite`: the composite against the path tracer's ground truth.
//!
//! Each built-in scene is rendered once by the reference path tracer with a glossy sphere on its
//! table and a diffuse box on the floor behind the table's edge (the same random numbers with and
//! without them, so the ground truth's photo and composite differ only by the objects' influence).
//! Then the real-time side renders the same objects, at the same poses, into the same photo, in
//! two ways:
//! - **true inputs**: the renderer alone, given the TRUE depth (mesh from it), lights and SH9 of
//!   the environment; what is left is the renderer's own error;
//! - **estimated**: the whole pipeline from the stereo pair (clipped to [0, 1] and stored as 8-bit
//!   sRGB, as a camera would): stereo → mesh → lights → render; compared with the truth clipped
//!   to [0, 1].
//!
//! For every shading mode, shadow mode, shadow-map size and filter width: mean absolute error
//! (linear light) and PSNR over the whole image, the objects, and their shadows, and the render
//! time, next to the path tracer's time for the same composite. Writes `composite.md`,
//! `composite.json`, `composite_error_vs_time.png` and, per scene, the truth and both
//! composites with the first configuration (`NAME_truth.png`, `NAME_true_inputs.png`,
//! `NAME_estimated.png`).
//!
//! With `--max-triangles N` (repeatable) the estimated composite of the first configuration is
//! also rendered with the scene mesh simplified to each budget, next to the full grid: how few
//! triangles the shadow receiver and occluder needs at equal quality (issue 5; the thesis meshed
//! every pixel, 1.8 M triangles for a 2820×1920 photo).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use parallax::context::{Context, ContextOptions};
use parallax::image::{Image, Raster};
use parallax::mesh::MeshOptions;
use parallax::render::compare::{
    compare_true_inputs, render_truth, ComparisonSetup, ReferenceTruth, RegionErrors,
};
use parallax::render::{RenderOptions, ShadingMode, ShadowMode};
use parallax::scene::Scene;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::plot::{nice_ceiling, scatter, Axes, Point};

/// Arguments of `parallax eval composite`.
#[derive(clap::Args, Debug)]
pub struct CompositeArgs {
    /// Built-in scene to evaluate (repeatable).
    #[arg(long = "scene", value_name = "NAME",
          default_values = ["room", "two-lights", "clutter", "window"])]
    scenes: Vec<String>,
    /// Image width, pixels (the height keeps the rig's 4:3).
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Path-tracing samples per pixel of the ground truth and of the stereo pair.
    #[arg(long, default_value_t = 32)]
    spp: u32,
    /// `full`: both shading modes × every shadow mode, shadow maps 512–4096, filter radii 0–8;
    /// `quick`: PBR shading with each shadow mode at the default size and filter.
    #[arg(long, default_value = "full", value_name = "full|quick")]
    configs: String,
    /// Also render the estimated composite (first configuration) with the scene mesh simplified
    /// to at most this many triangles (repeatable), next to the full grid.
    #[arg(long = "max-triangles", value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..))]
    max_triangles: Vec<u32>,
    /// Where the tables, plot and images go.
    #[arg(long, default_value = "target/eval-composite", value_name = "DIR")]
    out: PathBuf,
    #[command(flatten)]
    common: CommonArgs,
}

/// One measured configuration of one scene.
#[derive(serde::Serialize)]
struct Row {
    scene: String,
    /// `true` (TRUE depth and lights) or `estimated` (the whole pipeline).
    inputs: &'static str,
    config: String,
    errors: RegionErrors,
    render_ms: f64,
}

/// Per scene: the truth's cost and the estimation stages' time.
#[derive(serde::Serialize)]
struct SceneSummary {
    scene: String,
    width: u32,
    height: u32,
    reference_spp: u32,
    reference_seconds: f64,
    /// Stereo, mesh and lighting estimate of the pipeline, milliseconds (once per scene: moving
    /// or re-rendering artefacts reuses them).
    estimation_ms: f64,
    warnings: Vec<String>,
}

/// The estimated composite (first configuration) with one scene-mesh triangle budget.
#[derive(serde::Serialize)]
struct BudgetRow {
    scene: String,
    /// The configuration rendered (the first one).
    config: String,
    /// The budget; `None` = the full grid (a vertex per pixel).
    max_triangles: Option<usize>,
    /// Triangles of the mesh rendered.
    triangles: usize,
    errors: RegionErrors,
    /// A re-render with that mesh (after an untimed one that uploads it), milliseconds.
    render_ms: f64,
}

#[derive(serde::Serialize)]
struct Report {
    scenes: Vec<SceneSummary>,
    rows: Vec<Row>,
    budgets: Vec<BudgetRow>,
}

fn configurations(which: &str) -> Result<Vec<RenderOptions>> {
    let base = RenderOptions::default();
    let modes = [
        ShadowMode::ThesisEsm,
        ShadowMode::Evsm,
        ShadowMode::Pcss,
        ShadowMode::Off,
    ];
    let shading_modes: &[ShadingMode] = match which {
        "quick" => &[ShadingMode::Pbr],
        "full" => &[ShadingMode::Pbr, ShadingMode::Thesis],
        other => {
            return Err(Error::invalid(format!(
                "--configs {other:?}: full or quick"
            )))
        }
    };
    let mut configs = Vec::new();
    for &shading in shading_modes {
        for shadows in modes {
            configs.push(RenderOptions {
                shading,
                shadows,
                ..base
            });
        }
    }
    if which == "full" {
        for shadow_map_size in [512, 2048, 4096] {
            for shadows in [ShadowMode::ThesisEsm, ShadowMode::Pcss] {
                configs.push(RenderOptions {
                    shadows,
                    shadow_map_size,
                    ..base
                });
            }
        }
        for filter_radius in [0, 4, 8] {
            for shadows in [ShadowMode::ThesisEsm, ShadowMode::Evsm] {
                configs.push(RenderOptions {
                    shadows,
                    filter_radius,
                    ..base
                });
            }
        }
    }
    Ok(configs)
}

fn label(o: &RenderOptions) -> String {
    let shading = match o.shading {
        ShadingMode::Pbr => "pbr",
        ShadingMode::Thesis => "thesis",
    };
    let shadows = match o.shadows {
        ShadowMode::ThesisEsm => "esm",
        ShadowMode::Evsm => "evsm",
        ShadowMode::Pcss => "pcss",
        ShadowMode::Off => "off",
    };
    format!(
        "{shading} {shadows} {} r{}",
        o.shadow_map_size, o.filter_radius
    )
}

fn ldr(r: &Raster<[f32; 3]>) -> Image {
    Image::from_linear_rgb(&r.map(|c| c.map(|v| v.clamp(0.0, 1.0))))
}

/// What the whole pipeline gave on one scene.
struct Estimated {
    /// Stereo, mesh and lighting estimate, milliseconds.
    estimation_ms: f64,
    /// Per configuration: render milliseconds and errors.
    rows: Vec<(f64, RegionErrors)>,
    /// The first configuration's composite.
    first: Raster<[f32; 3]>,
    /// Per mesh budget (the full grid first): budget, triangles, render milliseconds, errors.
    budgets: Vec<(Option<usize>, usize, f64, RegionErrors)>,
    /// The trace's warnings, once each.
    warnings: Vec<String>,
}

/// The whole pipeline on the truth's stereo pair, with the truth's objects at their poses.
fn estimated(
    context: &Arc<Context>,
    truth: &ReferenceTruth,
    configs: &[RenderOptions],
    max_triangles: &[u32],
) -> Result<Estimated> {
    let right = truth
        .right
        .as_ref()
        .ok_or_else(|| Error::Internal("the truth was rendered without its right view".into()))?;
    let mut scene = Scene::new(context.clone());
    let (left, right) = (ldr(&truth.photo), ldr(right));
    scene.set_stereo_pair(&left.view(), &right.view())?;
    scene.set_calibration(truth.calibration)?;
    for (artefact, transform) in &truth.artefacts {
        scene.add_artefact(artefact.clone(), *transform)?;
    }
    // A host knows where it puts its objects; the environment is built around the first one,
    // as the true inputs' probe is.
    if let Some((_, transform)) = truth.artefacts.first() {
        scene.set_insertion_point(transform.w_axis.truncate().to_array())?;
    }
    let mut warnings = Vec::new();
    let start = Instant::now();
    scene.mesh()?;
    warnings.extend(scene.last_trace().warnings().iter().cloned());
    scene.lighting_estimate()?;
    warnings.extend(scene.last_trace().warnings().iter().cloned());
    scene.environment()?;
    let estimation_ms = start.elapsed().as_secs_f64() * 1e3;
    // An untimed render first, as for the true inputs: the figures are re-renders (an artefact
    // moved), the first render of a context also compiles the pipelines.
    if let Some(config) = configs.first() {
        scene.render(config)?;
    }
    let mut first = None;
    let mut rows = Vec::new();
    for config in configs {
        let start = Instant::now();
        let out = scene.render(config)?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        warnings.extend(scene.last_trace().warnings().iter().cloned());
        rows.push((ms, truth.errors(&out.composite, true)));
        first.get_or_insert(out.composite);
    }
    let mut budgets = Vec::new();
    let budget_config = configs.first().filter(|_| !max_triangles.is_empty());
    if let Some(config) = budget_config {
        let full = MeshOptions {
            max_triangles: None,
            ..scene.mesh_options()
        };
        let asked = max_triangles.iter().map(|&n| Some(n as usize));
        for budget in std::iter::once(None).chain(asked) {
            scene.set_mesh_options(MeshOptions {
                max_triangles: budget,
                ..full
            })?;
            let triangles = scene.mesh()?.triangle_count();
            scene.render(config)?;
            let start = Instant::now();
            let out = scene.render(config)?;
            let ms = start.elapsed().as_secs_f64() * 1e3;
            warnings.extend(scene.last_trace().warnings().iter().cloned());
            budgets.push((budget, triangles, ms, truth.errors(&out.composite, true)));
        }
    }
    warnings.sort();
    warnings.dedup();
    Ok(Estimated {
        estimation_ms,
        rows,
        first: first.unwrap_or_else(|| truth.photo.clone()),
        budgets,
        warnings,
    })
}

/// Evaluates every scene and writes the report.
pub fn run(args: CompositeArgs) -> Result<()> {
    let configs = configurations(&args.configs)?;
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let context = Arc::new(Context::new(ContextOptions::default())?);
    let (renderer, _) = context.renderer()?;
    let mut report = Report {
        scenes: Vec::new(),
        rows: Vec::new(),
        budgets: Vec::new(),
    };
    let progress = args.common.progress(
        args.scenes.len() as u64,
        "scenes (path tracing, then rendering)",
    );
    for name in &args.scenes {
        let setup = ComparisonSetup::for_scene(name, args.width, args.spp, configs.clone())?;
        let truth = render_truth(&setup, true)?;
        let true_run = compare_true_inputs(&renderer, &truth, &configs)?;
        let estimated = estimated(&context, &truth, &configs, &args.max_triangles)?;
        let (w, h) = truth.size();
        for r in &true_run.rows {
            report.rows.push(Row {
                scene: name.clone(),
                inputs: "true",
                config: label(&r.options),
                errors: RegionErrors {
                    image: r.image,
                    artefact: r.artefact,
                    shadow: r.shadow,
                    affected: r.affected,
                },
                render_ms: r.render_ms,
            });
        }
        for (config, (ms, errors)) in configs.iter().zip(estimated.rows) {
            report.rows.push(Row {
                scene: name.clone(),
                inputs: "estimated",
                config: label(config),
                errors,
                render_ms: ms,
            });
        }
        let image = |stem: &str| args.out.join(format!("{name}_{stem}.png"));
        Image::from_linear_rgb(&truth.composite).save_png(image("truth"))?;
        if let Some(ours) = &true_run.first {
            Image::from_linear_rgb(&ours.composite).save_png(image("true_inputs"))?;
        }
        Image::from_linear_rgb(&estimated.first).save_png(image("estimated"))?;
        for (max_triangles, triangles, render_ms, errors) in estimated.budgets {
            report.budgets.push(BudgetRow {
                scene: name.clone(),
                config: configs.first().map(label).unwrap_or_default(),
                max_triangles,
                triangles,
                errors,
                render_ms,
            });
        }
        report.scenes.push(SceneSummary {
            scene: name.clone(),
            width: w,
            height: h,
            reference_spp: truth.samples_per_pixel,
            reference_seconds: truth.reference_seconds,
            estimation_ms: estimated.estimation_ms,
            warnings: estimated.warnings,
        });
        progress.inc(1);
    }
    progress.finish_and_clear();
    let markdown = markdown(&report, &args);
    std::fs::write(args.out.join("composite.md"), &markdown)
        .map_err(|e| Error::io(args.out.join("composite.md"), e))?;
    let json = serde_json::to_string_pretty(&report)
        .map_err(|e| Error::Internal(format!("composite JSON: {e}")))?;
    std::fs::write(args.out.join("composite.json"), json)
        .map_err(|e| Error::io(args.out.join("composite.json"), e))?;
    plot(&report)?.save_png(args.out.join("composite_error_vs_time.png"))?;
    if !args.common.quiet {
        println!("{markdown}");
    }
    args.common.finish(&parallax::trace::Trace::new())
}

fn markdown(report: &Report, args: &CompositeArgs) -> String {
    let mut s = format!(
        "Scenes rendered at width {} by the reference path tracer ({} spp); MAE in linear light, \
         PSNR with peak 1. `true`: TRUE depth, lights and SH9; `estimated`: stereo → mesh → \
         lights → render from the 8-bit pair, against the truth clipped to [0, 1]. Render time: \
         the whole render call after one untimed warm-up (uploads, shadow maps, readback; \
         `estimated` through `Scene::render`, its depth, mesh and lights reused). Both sides \
         render the objects at the truth's poses. Speed-up: the path tracer's time for the same composite over the \
         render time.\n\n",
        args.width, args.spp
    );
    for sc in &report.scenes {
        let _ = writeln!(
            s,
            "## {} ({}×{})\n\nReference: {} spp in {:.2} s. Estimation (stereo, mesh, lights): \
             {:.0} ms.{}\n",
            sc.scene,
            sc.width,
            sc.height,
            sc.reference_spp,
            sc.reference_seconds,
            sc.estimation_ms,
            if sc.warnings.is_empty() {
                String::new()
            } else {
                format!(" Warnings: {}.", sc.warnings.join("; "))
            }
        );
        s.push_str(
            "| inputs | config | MAE image | PSNR image | MAE artefact | PSNR artefact | MAE shadow | PSNR shadow | render ms | speed-up |\n\
             |---|---|---|---|---|---|---|---|---|---|\n",
        );
        for r in report.rows.iter().filter(|r| r.scene == sc.scene) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.1} | {:.0}× |",
                r.inputs,
                r.config,
                error_cells(&r.errors),
                r.render_ms,
                sc.reference_seconds * 1e3 / r.render_ms.max(1e-9)
            );
        }
        s.push('\n');
        let budgets: Vec<&BudgetRow> = report
            .budgets
            .iter()
            .filter(|b| b.scene == sc.scene)
            .collect();
        if let Some(first) = budgets.first() {
            let _ = writeln!(
                s,
                "Scene mesh budget (estimated inputs, {}):\n\n\
                 | max triangles | triangles | MAE image | PSNR image | MAE artefact | PSNR artefact | MAE shadow | PSNR shadow | render ms |\n\
                 |---|---|---|---|---|---|---|---|---|",
                first.config
            );
            for b in &budgets {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {:.1} |",
                    b.max_triangles
                        .map_or("full grid".to_string(), |n| n.to_string()),
                    b.triangles,
                    error_cells(&b.errors),
                    b.render_ms,
                );
            }
            s.push('\n');
        }
    }
    s.push_str(
        "Plot `composite_error_vs_time.png`: x = render time (log, 10 ms – 100 s), y = MAE over \
         the artefact and shadow regions; filled squares = true inputs, outlines = estimated; \
         colour = scene (red room, green two-lights, blue clutter, orange window); the path \
         tracer's own time is a black outline at zero error.\n",
    );
    s
}

/// The table cells "MAE image | PSNR image | MAE artefact | PSNR artefact | MAE shadow | PSNR
/// shadow".
fn error_cells(e: &RegionErrors) -> String {
    format!(
        "{:.4} | {:.2} | {:.4} | {:.2} | {:.4} | {:.2}",
        e.image.mae, e.image.psnr, e.artefact.mae, e.artefact.psnr, e.shadow.mae, e.shadow.psnr
    )
}

fn plot(report: &Report) -> Result<Image> {
    let colour = |scene: &str| match scene {
        "room" => [200, 30, 30],
        "two-lights" => [30, 150, 30],
        "clutter" => [30, 60, 200],
        _ => [230, 130, 0],
    };
    let mut points: Vec<Point> = report
        .rows
        .iter()
        .map(|r| Point {
            ms: r.render_ms,
            error: r.errors.affected.mae,
            colour: colour(&r.scene),
            hollow: r.inputs == "estimated",
        })
        .collect();
    points.extend(report.scenes.iter().map(|s| Point {
        ms: s.reference_seconds * 1e3,
        error: 0.0,
        colour: [0, 0, 0],
        hollow: true,
    }));
    let error_max = nice_ceiling(points.iter().map(|p| p.error).fold(0.0, f64::max));
    scatter(
        &points,
        &Axes {
            decade_lo: 1,
            decade_hi: 5,
            error_max,
        },
    )
}

//! `parallax mesh`: stereo pair or depth → scene mesh → GLB / PLY / OBJ, through the Scene (so the
//! report shows stereo, depth, mesh.grid, mesh.simplify, mesh, camera).

use std::path::PathBuf;

use parallax::mesh::export::{
    write_glb, write_mesh_ply, write_obj, write_point_cloud_ply, GlbTexture,
};
use parallax::mesh::MeshOptions;
use parallax::trace::Trace;
use parallax::{Error, Result};

use crate::common::CommonArgs;
use crate::depth_input::{absorb, DepthInput};

/// Arguments of `parallax mesh`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    input: DepthInput,
    /// Output mesh: `.glb` (with the photo, --image or --left, as texture), `.ply` or `.obj`.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Simplify to at most N triangles (flat regions coarse, edges fine).
    #[arg(long, value_name = "N")]
    max_triangles: Option<usize>,
    /// Grid step in pixels (1 = a vertex per pixel).
    #[arg(long, default_value_t = 1)]
    step: u32,
    /// Most oblique view of a surface still meshed as continuous, degrees (cuts above it).
    #[arg(long, value_name = "DEG", default_value_t = 85.0)]
    max_angle: f32,
    /// Relative depth noise tolerated between neighbouring pixels.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.01)]
    depth_noise: f32,
    /// Keep every vertex's own fitted normal instead of giving the vertices on a detected
    /// support surface (floor, table, wall) the surface's normal.
    #[arg(long)]
    no_snap: bool,
    /// Also write the point cloud (coloured with the photo) as PLY.
    #[arg(long, value_name = "FILE.ply")]
    out_points: Option<PathBuf>,
    #[command(flatten)]
    common: CommonArgs,
}

/// Builds the mesh and writes it in the format the extension of `--out` names.
pub fn run(args: Args) -> Result<()> {
    let mut trace = Trace::new();
    let format = args
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    if !["glb", "ply", "obj"].contains(&format.as_str()) {
        return Err(Error::invalid(format!(
            "--out {}: the extension must be .glb, .ply or .obj",
            args.out.display()
        )));
    }
    let loaded = args.input.load(&mut trace)?;
    let mut scene = loaded.scene;
    scene.set_mesh_options(MeshOptions {
        step: args.step,
        max_grazing_angle_deg: args.max_angle,
        depth_noise: args.depth_noise,
        max_triangles: args.max_triangles,
        snap_to_surfaces: !args.no_snap,
    })?;
    let spinner = args.common.spinner("building the scene mesh");
    let mesh = scene.mesh();
    absorb(&mut trace, &scene);
    let mesh = args.common.or_warnings(&trace, mesh)?;
    let camera = scene.camera();
    absorb(&mut trace, &scene);
    let camera = args.common.or_warnings(&trace, camera)?;
    spinner.finish_and_clear();
    trace.time("mesh.export", "writing --out", |_| match format.as_str() {
        "glb" => {
            let texture = loaded
                .photo
                .as_ref()
                .map(GlbTexture::from_image)
                .transpose()?;
            write_glb(&mesh, texture.as_ref(), &args.out)
        }
        "ply" => write_mesh_ply(&mesh, &args.out),
        _ => {
            let photo = args.input.image.as_ref().or(args.input.left.as_ref());
            let texture = photo.map(|p| p.display().to_string());
            write_obj(&mesh, &args.out, texture.as_deref())
        }
    })?;
    if let Some(path) = &args.out_points {
        let colours = loaded.photo.as_ref().map(|p| p.to_linear_rgb());
        let depth = scene.depth()?;
        write_point_cloud_ply(&depth, &camera, colours.as_ref(), path)?;
    }
    if !args.common.quiet {
        eprintln!(
            "parallax: {} triangles, {} vertices, near {:.3} m, far {:.3} m, f = {:.1} px → {}",
            mesh.triangle_count(),
            mesh.vertex_count(),
            camera.near,
            camera.far,
            camera.fx,
            args.out.display()
        );
    }
    args.common.finish(&trace)
}

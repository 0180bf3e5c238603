//! Picking on real data: the Middlebury Motorcycle pair's ground-truth disparity (skipped when
//! `../shared/data` is absent). The stereo matcher is not part of this check yet: the mesh is built
//! from the true disparity, so this tests calibration, depth, meshing and picking on a real camera.

use std::path::PathBuf;

use glam::Vec2;
use parallax::camera::{Camera, StereoCalibration};
use parallax::image::{ImageLimits, Raster};
use parallax::mesh::{pick, Bvh, MeshOptions, SceneMesh};

fn data_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("PARALLAX_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")));
    dir.join("middlebury2014-q/Motorcycle")
        .is_dir()
        .then_some(dir)
}

#[test]
fn pick_on_motorcycle_lands_on_true_depth() {
    let Some(dir) = data_dir() else {
        eprintln!("skipped: no ../shared/data");
        return;
    };
    let scene = dir.join("middlebury2014-q/Motorcycle");
    let calib = StereoCalibration::load_middlebury(scene.join("calib.txt")).unwrap();
    let disparity = Raster::read_pfm(scene.join("disp0GT.pfm"), &ImageLimits::default()).unwrap();
    let depth = disparity.map(|&d| calib.depth_from_disparity(d));
    let (w, h) = (depth.width(), depth.height());
    let camera = Camera::from_calibration(&calib, w as u32, h as u32)
        .unwrap()
        .with_clip_from_depth(&depth)
        .unwrap();
    for max_triangles in [None, Some(100_000)] {
        let options = MeshOptions {
            max_triangles,
            ..Default::default()
        };
        let mesh = SceneMesh::from_depth(&depth, &camera, &options).unwrap();
        let bvh = Bvh::new(&mesh);
        let (mut checked, mut within) = (0, 0);
        for y in (10..h - 10).step_by(23) {
            for x in (10..w - 10).step_by(23) {
                let truth = *depth.get(x, y);
                if !truth.is_finite() {
                    continue;
                }
                let Some(hit) = pick(&bvh, &camera, Vec2::new(x as f32 + 0.5, y as f32 + 0.5))
                else {
                    continue;
                };
                checked += 1;
                if ((-hit.point.z - truth) / truth).abs() <= 0.02 {
                    within += 1;
                }
            }
        }
        let fraction = within as f64 / checked as f64;
        eprintln!("{max_triangles:?}: {within}/{checked} picks within 2 % of the true depth");
        assert!(checked > 300);
        assert!(
            fraction > 0.97,
            "{max_triangles:?}: only {fraction:.3} within 2 %"
        );
    }
}

//! Built-in scenes after the thesis' synthetic rooms (§4.1, §4.2.2): box-like rooms with textured
//! walls and floor (so that stereo matching has texture everywhere), a table with objects, and a
//! 58 mm stereo baseline.
//!
//! World: metres, +Y up, the room spans x ∈ [−2, 2], y ∈ [0, 2.6], z ∈ [−4, 1.5]; the rig stands
//! at (0, 1.3, 1) looking at (0, 0.75, −2).

use super::description::{
    CameraRig, Environment, Light, Material, Object, Pattern, Portal, Scene, Shape, Texture,
    Transform,
};
use crate::error::{Error, Result};

/// Names accepted by [`builtin`].
pub const BUILTIN_SCENES: &[&str] = &["room", "two-lights", "clutter", "window"];

const ROOM_X: f32 = 2.0;
const ROOM_H: f32 = 2.6;
const ROOM_BACK: f32 = -4.0;
const ROOM_FRONT: f32 = 1.5;
const TABLE_Z: f32 = -1.8;
const TABLE_TOP: f32 = 0.75;

/// A built-in scene by name ([`BUILTIN_SCENES`]):
/// - `room`: a table with a glossy sphere and a textured box, one ceiling area light (the thesis'
///   synthetic scene 1);
/// - `two-lights`: the same room lit by two sphere lights, so every object casts two shadows
///   (thesis Fig. 3.12);
/// - `clutter`: many objects on the floor and the table occluding each other (Fig. 4.7 b);
/// - `window`: a sun (directional, 0.53°) through a window in the left wall plus a dim sky (the
///   window is a portal, so both are sampled through it).
///
/// # Errors
/// `InvalidArgument` for an unknown name (the message lists the known ones).
pub fn builtin(name: &str) -> Result<Scene> {
    let scene = match name {
        "room" => room(),
        "two-lights" => two_lights(),
        "clutter" => clutter(),
        "window" => window(),
        other => {
            return Err(Error::invalid(format!(
                "unknown built-in scene {other:?}; built-in scenes: {}",
                BUILTIN_SCENES.join(", ")
            )))
        }
    };
    scene.validate()?;
    Ok(scene)
}

fn rig() -> CameraRig {
    CameraRig {
        width: 640,
        height: 480,
        fov_x_deg: Some(60.0),
        focal_px: None,
        baseline_m: 0.058,
        position: [0.0, 1.3, 1.0],
        look_at: [0.0, TABLE_TOP, -2.0],
        up: [0.0, 1.0, 0.0],
    }
}

fn object(name: &str, shape: Shape, material: Material, transform: Transform) -> Object {
    Object {
        name: name.into(),
        shape,
        material,
        transform,
    }
}

fn rotated(translation: [f32; 3], rotation_deg: [f32; 3]) -> Transform {
    Transform {
        translation,
        rotation_deg,
        scale: [1.0; 3],
    }
}

fn wall_material() -> Material {
    Material {
        base_color: [0.78, 0.75, 0.68],
        texture: Some(Texture {
            pattern: Pattern::Noise { octaves: Some(5) },
            scale: 3.0,
            color: [0.5, 0.47, 0.42],
            speckle: 0.3,
        }),
        ..Material::default()
    }
}

fn floor_material() -> Material {
    Material {
        base_color: [0.5, 0.33, 0.2],
        texture: Some(Texture {
            pattern: Pattern::Wood,
            scale: 1.5,
            color: [0.26, 0.15, 0.08],
            speckle: 0.2,
        }),
        roughness: 0.6,
        ..Material::default()
    }
}

fn table_material() -> Material {
    Material {
        base_color: [0.62, 0.45, 0.3],
        texture: Some(Texture {
            pattern: Pattern::Wood,
            scale: 4.0,
            color: [0.35, 0.22, 0.12],
            speckle: 0.2,
        }),
        roughness: 0.45,
        ..Material::default()
    }
}

/// Floor, ceiling and four walls (the one behind the camera included, so the room is closed).
/// `skip_left` leaves out the left wall (the window scene builds its own).
fn shell(skip_left: bool) -> Vec<Object> {
    let depth = ROOM_FRONT - ROOM_BACK;
    let mid_z = (ROOM_FRONT + ROOM_BACK) / 2.0;
    let width = 2.0 * ROOM_X;
    let mut objects = vec![
        object(
            "floor",
            Shape::Plane {
                size: [width, depth],
            },
            floor_material(),
            Transform::at(0.0, 0.0, mid_z),
        ),
        object(
            "ceiling",
            Shape::Plane {
                size: [width, depth],
            },
            Material {
                texture: Some(Texture {
                    pattern: Pattern::Noise { octaves: Some(3) },
                    scale: 2.0,
                    color: [0.7, 0.7, 0.7],
                    speckle: 0.2,
                }),
                ..Material::diffuse([0.85, 0.85, 0.85])
            },
            rotated([0.0, ROOM_H, mid_z], [0.0, 180.0, 0.0]),
        ),
        object(
            "back wall",
            Shape::Plane {
                size: [width, ROOM_H],
            },
            wall_material(),
            rotated([0.0, ROOM_H / 2.0, ROOM_BACK], [0.0, 90.0, 0.0]),
        ),
        object(
            "front wall",
            Shape::Plane {
                size: [width, ROOM_H],
            },
            wall_material(),
            rotated([0.0, ROOM_H / 2.0, ROOM_FRONT], [0.0, -90.0, 0.0]),
        ),
        object(
            "right wall",
            Shape::Plane {
                size: [ROOM_H, depth],
            },
            Material {
                base_color: [0.62, 0.7, 0.78],
                ..wall_material()
            },
            rotated([ROOM_X, ROOM_H / 2.0, mid_z], [0.0, 0.0, 90.0]),
        ),
    ];
    if !skip_left {
        objects.push(object(
            "left wall",
            Shape::Plane {
                size: [ROOM_H, depth],
            },
            Material {
                base_color: [0.8, 0.68, 0.6],
                ..wall_material()
            },
            rotated([-ROOM_X, ROOM_H / 2.0, mid_z], [0.0, 0.0, -90.0]),
        ));
    }
    objects
}

/// A table 1.2 × 0.7 m, top at [`TABLE_TOP`], centred at (x, TABLE_Z).
fn table(x: f32) -> Vec<Object> {
    let mut parts = vec![object(
        "table top",
        Shape::Box {
            size: [1.2, 0.05, 0.7],
        },
        table_material(),
        Transform::at(x, TABLE_TOP - 0.025, TABLE_Z),
    )];
    for (dx, dz) in [(-0.55, -0.3), (0.55, -0.3), (-0.55, 0.3), (0.55, 0.3)] {
        parts.push(object(
            "table leg",
            Shape::Box {
                size: [0.05, TABLE_TOP - 0.05, 0.05],
            },
            table_material(),
            Transform::at(x + dx, (TABLE_TOP - 0.05) / 2.0, TABLE_Z + dz),
        ));
    }
    parts
}

fn glossy_sphere(at: [f32; 3], radius: f32) -> Object {
    object(
        "sphere",
        Shape::Sphere {
            radius,
            segments: Some(64),
        },
        Material {
            base_color: [0.75, 0.12, 0.08],
            roughness: 0.3,
            texture: Some(Texture {
                pattern: Pattern::Noise { octaves: Some(3) },
                scale: 12.0,
                color: [0.55, 0.08, 0.05],
                speckle: 0.1,
            }),
            ..Material::default()
        },
        Transform::at(at[0], at[1] + radius, at[2]),
    )
}

fn checker_box(at: [f32; 3], size: f32, yaw: f32) -> Object {
    object(
        "box",
        Shape::Box { size: [size; 3] },
        Material {
            base_color: [0.15, 0.3, 0.65],
            texture: Some(Texture {
                pattern: Pattern::Checker,
                scale: 20.0,
                color: [0.75, 0.75, 0.7],
                speckle: 0.15,
            }),
            ..Material::default()
        },
        rotated([at[0], at[1] + size / 2.0, at[2]], [yaw, 0.0, 0.0]),
    )
}

fn ceiling_light() -> Light {
    Light::Rect {
        center: [0.0, ROOM_H - 0.02, -1.6],
        edge_u: [0.6, 0.0, 0.0],
        edge_v: [0.0, 0.0, 0.6],
        radiance: [16.0, 15.0, 13.5],
    }
}

fn room() -> Scene {
    let mut objects = shell(false);
    objects.extend(table(0.0));
    objects.push(glossy_sphere([-0.3, TABLE_TOP, TABLE_Z + 0.05], 0.12));
    objects.push(checker_box([0.3, TABLE_TOP, TABLE_Z - 0.05], 0.2, 30.0));
    Scene {
        name: "room".into(),
        camera: rig(),
        objects,
        lights: vec![ceiling_light()],
        environment: Environment::Black,
        portals: Vec::new(),
    }
}

fn two_lights() -> Scene {
    let mut scene = room();
    scene.name = "two-lights".into();
    scene.lights = vec![
        Light::Sphere {
            center: [-1.0, 2.0, -1.2],
            radius: 0.08,
            radiance: [170.0, 163.0, 150.0],
        },
        Light::Sphere {
            center: [1.1, 1.8, -2.4],
            radius: 0.08,
            radiance: [115.0, 122.0, 140.0],
        },
    ];
    scene
}

fn clutter() -> Scene {
    let mut objects = shell(false);
    objects.extend(table(0.2));
    objects.push(glossy_sphere([-0.1, TABLE_TOP, TABLE_Z + 0.15], 0.1));
    objects.push(checker_box([0.45, TABLE_TOP, TABLE_Z - 0.1], 0.18, 20.0));
    objects.push(object(
        "vase",
        Shape::Cylinder {
            radius: 0.06,
            height: 0.3,
            segments: Some(48),
        },
        Material {
            base_color: [0.2, 0.55, 0.3],
            roughness: 0.35,
            texture: Some(Texture {
                pattern: Pattern::Noise { octaves: Some(2) },
                scale: 20.0,
                color: [0.1, 0.3, 0.15],
                speckle: 0.1,
            }),
            ..Material::default()
        },
        Transform::at(0.15, TABLE_TOP + 0.15, TABLE_Z - 0.2),
    ));
    objects.push(object(
        "ring",
        Shape::Torus {
            major_radius: 0.09,
            minor_radius: 0.03,
            segments: Some(48),
        },
        Material {
            base_color: [0.95, 0.75, 0.35],
            metallic: 1.0,
            roughness: 0.3,
            ..Material::default()
        },
        rotated([0.6, TABLE_TOP + 0.03, TABLE_Z + 0.2], [0.0, 0.0, 0.0]),
    ));
    // On the floor, in front of and beside the table, overlapping in the view.
    objects.push(checker_box([-0.9, 0.0, -1.3], 0.45, -15.0));
    objects.push(checker_box([-0.75, 0.45, -1.35], 0.25, 25.0));
    objects.push(glossy_sphere([-0.35, 0.0, -0.9], 0.15));
    objects.push(object(
        "stool",
        Shape::Cylinder {
            radius: 0.18,
            height: 0.45,
            segments: Some(48),
        },
        table_material(),
        Transform::at(0.75, 0.225, -1.1),
    ));
    objects.push(object(
        "ball",
        Shape::Sphere {
            radius: 0.09,
            segments: Some(48),
        },
        Material::diffuse([0.85, 0.8, 0.3]),
        Transform::at(0.75, 0.45 + 0.09, -1.1),
    ));
    objects.push(object(
        "crate",
        Shape::Box {
            size: [0.5, 0.6, 0.4],
        },
        Material {
            texture: Some(Texture {
                pattern: Pattern::Wood,
                scale: 3.0,
                color: [0.3, 0.2, 0.1],
                speckle: 0.25,
            }),
            ..Material::diffuse([0.6, 0.45, 0.3])
        },
        rotated([1.3, 0.3, -2.8], [10.0, 0.0, 0.0]),
    ));
    objects.push(object(
        "tyre",
        Shape::Torus {
            major_radius: 0.2,
            minor_radius: 0.07,
            segments: Some(48),
        },
        Material {
            roughness: 0.7,
            ..Material::diffuse([0.08, 0.08, 0.09])
        },
        rotated([-1.4, 0.27, -2.6], [30.0, 90.0, 0.0]),
    ));
    objects.push(object(
        "column",
        Shape::Cylinder {
            radius: 0.12,
            height: ROOM_H,
            segments: Some(48),
        },
        wall_material(),
        Transform::at(-1.5, ROOM_H / 2.0, -3.4),
    ));
    Scene {
        name: "clutter".into(),
        camera: rig(),
        objects,
        lights: vec![ceiling_light()],
        environment: Environment::Black,
        portals: Vec::new(),
    }
}

fn window() -> Scene {
    let mut objects = shell(true);
    // The left wall (x = −2, 10 cm thick) around a window opening z ∈ [−2.6, −1.2], y ∈ [0.9, 2.0].
    let (z0, z1, y0, y1) = (-2.6f32, -1.2f32, 0.9f32, 2.0f32);
    let wall_x = -ROOM_X - 0.05;
    let mut block = |name: &str, zmin: f32, zmax: f32, ymin: f32, ymax: f32| {
        objects.push(object(
            name,
            Shape::Box {
                size: [0.1, ymax - ymin, zmax - zmin],
            },
            Material {
                base_color: [0.8, 0.68, 0.6],
                ..wall_material()
            },
            Transform::at(wall_x, (ymin + ymax) / 2.0, (zmin + zmax) / 2.0),
        ));
    };
    block("left wall (back part)", ROOM_BACK, z0, 0.0, ROOM_H);
    block("left wall (front part)", z1, ROOM_FRONT, 0.0, ROOM_H);
    block("left wall (below window)", z0, z1, 0.0, y0);
    block("left wall (above window)", z0, z1, y1, ROOM_H);
    objects.extend(table(0.2));
    objects.push(glossy_sphere([-0.1, TABLE_TOP, TABLE_Z + 0.05], 0.12));
    objects.push(checker_box([0.5, TABLE_TOP, TABLE_Z - 0.05], 0.2, 30.0));
    objects.push(checker_box([-0.9, 0.0, -1.5], 0.35, 10.0));
    Scene {
        name: "window".into(),
        camera: rig(),
        objects,
        lights: vec![Light::Directional {
            direction: [0.8, -0.6, -0.1],
            irradiance: [9.0, 8.5, 7.5],
            angular_diameter_deg: 0.53,
        }],
        environment: Environment::Sky {
            zenith: [1.2, 1.7, 3.0],
            horizon: [2.6, 2.7, 2.9],
            ground: [0.8, 0.7, 0.6],
        },
        // Across the opening on the wall's outer face, so that the sun's beam reaches the sill
        // and the jambs as it does through the real opening.
        portals: vec![Portal {
            center: [wall_x - 0.05, (y0 + y1) / 2.0, (z0 + z1) / 2.0],
            edge_u: [0.0, 0.0, z1 - z0],
            edge_v: [0.0, y1 - y0, 0.0],
        }],
    }
}

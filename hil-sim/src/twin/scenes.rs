//! Built-in named scenes with their rigs, used by the CLI, tests, benches
//! and dataset exporter. All at a working distance of about 0.5 m.

use std::sync::Arc;

use super::device::{look_at, Camera, Distortion, Intrinsics, Pinhole, Projector, Rig};
use super::error::TwinError;
use super::geometry::{Pose, Shape, V3};
use super::medium::Medium;
use super::mesh::Mesh;
use super::scene::{Albedo, Checkerboard, Material, Motion, Object, Scene, Texture};

mod rotor;
pub use rotor::{ROTOR_BLADES, ROTOR_CENTRE_M, ROTOR_REV_PER_S, ROTOR_TIP_RADIUS_M};

/// Radii of seed 001's two calibration spheres, metres.
pub const SPHERE_RADII_M: [f64; 2] = [0.0253967, 0.0253989];
/// Distance between their centres, metres.
pub const SPHERE_CENTRE_DISTANCE_M: f64 = 0.1001166;
/// The checkerboard of the `checkerboard` scene (9 x 7 squares of 20 mm: 8 x 6 inner corners).
pub const CHECKERBOARD: Checkerboard = Checkerboard {
    squares_x: 9,
    squares_y: 7,
    square_m: 0.02,
    dark: 0.06,
    light: 0.85,
};

/// Image sizes to build a scene at: small for tests, large for pictures and benches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Detail {
    /// Camera image (width, height), pixels.
    pub camera: (u32, u32),
    /// Projector DMD (width, height), pixels.
    pub projector: (u32, u32),
}

impl Default for Detail {
    /// A 640x480 camera and a 1280x800 DMD.
    fn default() -> Self {
        Detail {
            camera: (640, 480),
            projector: (1280, 800),
        }
    }
}

/// A built-in scene: name, one-line description and builder.
pub struct BuiltIn {
    /// Name used on the command line.
    pub name: &'static str,
    /// What it shows and what it is for.
    pub about: &'static str,
    /// Builds scene and rig at a level of detail.
    pub build: fn(&Detail) -> Result<(Scene, Rig), TwinError>,
}

/// Every built-in scene.
pub const BUILT_IN: &[BuiltIn] = &[
    BuiltIn {
        name: "plane",
        about: "tilted matte plane, one head (homography and phase-noise checks)",
        build: plane,
    },
    BuiltIn {
        name: "spheres",
        about: "two calibration spheres, R 25.3967 / 25.3989 mm, centres 100.1166 mm apart",
        build: spheres,
    },
    BuiltIn {
        name: "stereo-spheres",
        about: "the two calibration spheres seen by a stereo head: two cameras 170 mm apart, one projector between them",
        build: stereo_spheres,
    },
    BuiltIn {
        name: "prism",
        about: "prism with protrusions casting shadows and blind spots, one head",
        build: prism,
    },
    BuiltIn {
        name: "large-part",
        about: "wavy panel wider than one head's view, two heads with overlapping fields",
        build: large_part,
    },
    BuiltIn {
        name: "metal-part",
        about: "glossy machined part, 50:1 reflectivity range and saturating highlights",
        build: metal_part,
    },
    BuiltIn {
        name: "hdr-part",
        about: "polished curved metal beside a matte black block: highlights saturate, the black starves (high dynamic range)",
        build: hdr_part,
    },
    BuiltIn {
        name: "colour-part",
        about: "glossy painted plate in saturated red, green, blue and white quarters: one mono exposure saturates the white and starves the colours",
        build: colour_part,
    },
    BuiltIn {
        name: "colour-object",
        about: "multi-coloured sphere on a colour-patch board",
        build: colour_object,
    },
    BuiltIn {
        name: "fan",
        about: "four-blade fan spinning at 10 rev/s in front of a wall (dynamic)",
        build: fan,
    },
    BuiltIn {
        name: "falling",
        about: "sphere falling under gravity past a wall (dynamic)",
        build: falling,
    },
    BuiltIn {
        name: "rotor",
        about: "seed 001's rotor-engine model: spinner hub and 7 pitched blades (190 mm across) at 1177 rpm inside a static casing and stator struts, before a wall (dynamic; high-speed mode)",
        build: rotor::rotor,
    },
    BuiltIn {
        name: "checkerboard",
        about: "9x7 checkerboard target (20 mm squares), tilted, for calibration",
        build: checkerboard,
    },
    BuiltIn {
        name: "ring-3",
        about: "turbine-blade-like part (cambered airfoil, tapered, twisted 137 deg unevenly, domed root platform, tip shroud) inside a ring of three heads 120 deg apart looking down 43 deg: no two see it whole, all three do",
        build: super::ring_scenes::ring3,
    },
    BuiltIn {
        name: "ring-4",
        about: "the ring-3 turbine blade inside a ring of four heads 90 deg apart looking down 13 deg: no two see it whole, all four do",
        build: super::ring_scenes::ring4,
    },
    BuiltIn {
        name: "bumpy-mesh",
        about: "100k-triangle bumpy sphere mesh on a wall (BVH benchmark)",
        build: bumpy_mesh,
    },
];

/// Builds the built-in scene `name`.
pub fn built_in(name: &str, detail: &Detail) -> Result<(Scene, Rig), TwinError> {
    let b = BUILT_IN
        .iter()
        .find(|b| b.name == name)
        .ok_or_else(|| TwinError::UnknownScene(name.to_string()))?;
    (b.build)(detail)
}

pub(super) fn camera(name: &str, detail: &Detail, eye: V3, target: V3) -> Camera {
    let (w, h) = detail.camera;
    Camera {
        name: name.into(),
        model: Pinhole {
            intrinsics: Intrinsics::from_fov(w, h, 42.0),
            distortion: Distortion {
                k1: -0.08,
                k2: 0.02,
                p1: 0.0002,
                p2: -0.0001,
                k3: 0.0,
            },
            world_from_device: look_at(eye, target, V3::new(0.0, -1.0, 0.0)),
        },
    }
}

pub(super) fn projector(name: &str, detail: &Detail, eye: V3, target: V3) -> Projector {
    let (w, h) = detail.projector;
    let mut k = Intrinsics::from_fov(w, h, 56.0);
    // DMD projectors throw upwards: principal point near the bottom edge.
    k.cy = 0.85 * h as f64;
    Projector {
        name: name.into(),
        model: Pinhole {
            intrinsics: k,
            distortion: Distortion {
                k1: 0.02,
                ..Distortion::default()
            },
            // Aim the axis below the target so the upward throw centres on it.
            world_from_device: look_at(
                eye,
                target + V3::new(0.0, 0.09, 0.0),
                V3::new(0.0, -1.0, 0.0),
            ),
        },
        led_power: [1.0, 1.0, 1.0],
        defocus_sigma_px: 0.8,
        gamma: 1.0,
        reference_distance_m: 0.5,
    }
}

/// One head: camera at the origin looking along +z, projector 0.12 m to its right.
pub fn single_head(detail: &Detail) -> Rig {
    let target = V3::new(0.0, 0.0, 0.5);
    Rig {
        cameras: vec![camera("cam-a", detail, V3::zeros(), target)],
        projectors: vec![projector("proj-a", detail, V3::new(0.12, 0.0, 0.0), target)],
        medium: Medium::Air,
    }
}

/// Two heads 0.36 m apart, each aimed 0.1 m off centre so their fields overlap in the middle.
pub fn dual_head(detail: &Detail) -> Rig {
    let (ta, tb) = (V3::new(-0.1, 0.0, 0.5), V3::new(0.1, 0.0, 0.5));
    Rig {
        cameras: vec![
            camera("cam-a", detail, V3::new(-0.18, 0.0, 0.0), ta),
            camera("cam-b", detail, V3::new(0.18, 0.0, 0.0), tb),
        ],
        projectors: vec![
            projector("proj-a", detail, V3::new(-0.08, 0.0, 0.0), ta),
            projector("proj-b", detail, V3::new(0.08, 0.0, 0.0), tb),
        ],
        medium: Medium::Air,
    }
}

/// Half the stereo head's baseline, metres: its cameras are 170 mm apart.
pub const STEREO_HALF_BASELINE_M: f64 = 0.085;

/// A stereo head: cameras `cam-left` and `cam-right` (in that order) 170 mm apart,
/// converging on the point 0.5 m in front of their midpoint, and one projector at the
/// midpoint that only labels the surface. With the projector on the baseline, each
/// projector column lights one surface point per epipolar plane, so a column value is
/// found once on a rectified row.
pub fn stereo_head(detail: &Detail) -> Rig {
    let target = V3::new(0.0, 0.0, 0.5);
    let h = STEREO_HALF_BASELINE_M;
    Rig {
        cameras: vec![
            camera("cam-left", detail, V3::new(-h, 0.0, 0.0), target),
            camera("cam-right", detail, V3::new(h, 0.0, 0.0), target),
        ],
        projectors: vec![projector("proj", detail, V3::zeros(), target)],
        medium: Medium::Air,
    }
}

fn matte(r: f32, g: f32, b: f32) -> Material {
    Material::matte(Albedo::Constant([r, g, b]))
}

fn wall(z_m: f64, albedo: f32) -> Object {
    Object::new(
        "wall",
        Shape::Rect {
            half_x_m: 1.5,
            half_y_m: 1.5,
        },
        matte(albedo, albedo, albedo),
        Pose::translation(0.0, 0.0, z_m),
    )
}

fn with_ambient(objects: Vec<Object>) -> Scene {
    // About 5 % of a projector at full drive: visible, not dominant.
    Scene {
        objects,
        ambient_surface: [0.05; 3],
        ambient_direct: [0.01; 3],
    }
}

fn plane(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let pose = Pose::new(V3::new(0.0, 0.0, 0.5), V3::new(0.2, 0.3, 0.0));
    let obj = Object::new(
        "plane",
        Shape::Rect {
            half_x_m: 0.6,
            half_y_m: 0.6,
        },
        matte(0.8, 0.8, 0.8),
        pose,
    );
    Ok((with_ambient(vec![obj]), single_head(d)))
}

fn spheres(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    Ok((calibration_spheres(), single_head(d)))
}

fn stereo_spheres(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    Ok((calibration_spheres(), stereo_head(d)))
}

/// Seed 001's two spheres, centres on the x axis 0.5 m out, before a dim wall.
fn calibration_spheres() -> Scene {
    let half = 0.5 * SPHERE_CENTRE_DISTANCE_M;
    let s = |i: usize, x: f64| {
        Object::new(
            ["sphere-1", "sphere-2"][i],
            Shape::Sphere {
                radius_m: SPHERE_RADII_M[i],
            },
            matte(0.75, 0.75, 0.75),
            Pose::translation(x, 0.0, 0.5),
        )
    };
    with_ambient(vec![s(0, -half), s(1, half), wall(0.6, 0.3)])
}

fn prism(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let tilt = Pose::new(V3::new(0.0, 0.0, 0.52), V3::new(0.0, 0.5, 0.0));
    let body = Object::new(
        "prism",
        Shape::Cuboid {
            half_m: V3::new(0.06, 0.05, 0.04),
        },
        matte(0.7, 0.7, 0.7),
        tilt,
    );
    let bumps = [
        (-0.03, -0.025, 0.012),
        (0.02, 0.02, 0.02),
        (0.035, -0.03, 0.008),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(x, y, hz))| {
        let local = Pose::translation(x, y, -0.04 - hz);
        Object::new(
            &format!("protrusion-{i}"),
            Shape::Cuboid {
                half_m: V3::new(0.008, 0.008, hz),
            },
            matte(0.7, 0.7, 0.7),
            tilt * local,
        )
    });
    let mut objects: Vec<Object> = vec![body];
    objects.extend(bumps);
    objects.push(wall(0.62, 0.4));
    Ok((with_ambient(objects), single_head(d)))
}

fn large_part(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let mesh = Mesh::height_field(241, 121, 0.7, 0.35, |x, y| {
        0.015 * (x * 25.0).sin() * (y * 18.0).cos() - 0.02 * (x * 4.0).cos()
    })?;
    let panel = Object::new(
        "panel",
        Shape::Mesh(Arc::new(mesh)),
        matte(0.75, 0.72, 0.7),
        Pose::translation(0.0, 0.0, 0.5),
    );
    Ok((with_ambient(vec![panel, wall(0.65, 0.2)]), dual_head(d)))
}

fn metal_part(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    // Brushed and polished bands: diffuse reflectance 0.018 .. 0.9 (50:1).
    let bands = vec![[0.9f32; 3], [0.25; 3], [0.018; 3], [0.5; 3], [0.06; 3]];
    let metal = Material {
        albedo: Albedo::Stripes {
            period_m: 0.015,
            colours: bands,
        },
        specular: 4.0,
        shininess: 400.0,
        // Interreflections inside the machined part.
        ambient: [0.02; 3],
    };
    let mesh = Mesh::height_field(161, 161, 0.2, 0.2, |x, y| {
        0.03 * (1.0 - (x * x + y * y) / 0.02).max(0.0).sqrt()
    })?;
    let part = Object {
        name: "metal-part".into(),
        shape: Shape::Mesh(Arc::new(mesh)),
        material: metal,
        pose: Pose::translation(0.0, 0.0, 0.5),
        motion: Motion::Static,
    };
    let boss = Object::new(
        "boss",
        Shape::Sphere { radius_m: 0.02 },
        Material {
            albedo: Albedo::Constant([0.3; 3]),
            specular: 20.0,
            shininess: 200.0,
            ambient: [0.0; 3],
        },
        Pose::translation(0.06, -0.05, 0.47),
    );
    Ok((
        with_ambient(vec![part, boss, wall(0.56, 0.1)]),
        single_head(d),
    ))
}

/// Polished aluminium (a half-cylinder whose highlight band saturates the
/// sensor at full projection: diffuse 0.5, specular peak 6 x a white
/// diffuser, Blinn-Phong exponent 30, so about a fifth of its width
/// saturates) beside a matte black block (reflectance 0.15: at the standard
/// exposure its fringes are too weak for their orders to be counted), on a
/// grey wall: the two ends of the sensor's range in one view.
fn hdr_part(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let radius_m = 0.045;
    let mesh = Mesh::height_field(181, 121, 2.0 * radius_m, 0.15, |x, _| {
        0.7 * (radius_m * radius_m - x * x).max(0.0).sqrt()
    })?;
    let polished = Material {
        albedo: Albedo::Constant([0.5; 3]),
        specular: 6.0,
        shininess: 30.0,
        ambient: [0.0; 3],
    };
    let metal = Object {
        name: "polished-metal".into(),
        shape: Shape::Mesh(Arc::new(mesh)),
        material: polished,
        pose: Pose::translation(-0.05, 0.0, 0.5),
        motion: Motion::Static,
    };
    let black = Object::new(
        "matte-black",
        Shape::Cuboid {
            half_m: V3::new(0.04, 0.07, 0.02),
        },
        matte(0.15, 0.15, 0.15),
        Pose::new(V3::new(0.05, 0.0, 0.5), V3::new(0.0, -0.3, 0.0)),
    );
    Ok((
        with_ambient(vec![metal, black, wall(0.6, 0.3)]),
        single_head(d),
    ))
}

/// A painted plate: quarters of saturated red, green, blue and white paint
/// (reflectance 0.6 in its own band, 0.03 in the others; white 0.9) under
/// a clear coat whose gloss (peak 0.6 x a white diffuser, exponent 40) is
/// the same on every colour, tilted on a grey wall. Seen by a mono camera,
/// a colour reflects a quarter of what white does.
fn colour_part(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let (hi, lo) = (0.6f32, 0.03f32);
    let tex = Texture {
        width: 2,
        height: 2,
        rgb: vec![[hi, lo, lo], [lo, hi, lo], [lo, lo, hi], [0.9, 0.9, 0.9]],
        size_m: [0.2, 0.16],
    };
    let plate = Object {
        name: "painted-plate".into(),
        shape: Shape::Rect {
            half_x_m: 0.1,
            half_y_m: 0.08,
        },
        material: Material {
            albedo: Albedo::Texture(Arc::new(tex)),
            specular: 0.6,
            shininess: 40.0,
            ambient: [0.0; 3],
        },
        pose: Pose::new(V3::new(0.0, 0.0, 0.5), V3::new(0.15, -0.2, 0.0)),
        motion: Motion::Static,
    };
    Ok((with_ambient(vec![plate, wall(0.6, 0.3)]), single_head(d)))
}

fn colour_object(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let sectors = vec![
        [0.8, 0.1, 0.1],
        [0.1, 0.7, 0.1],
        [0.1, 0.2, 0.8],
        [0.8, 0.8, 0.1],
        [0.7, 0.1, 0.7],
        [0.1, 0.7, 0.7],
    ];
    let ball = Object::new(
        "colour-sphere",
        Shape::Sphere { radius_m: 0.05 },
        Material::matte(Albedo::Sectors(sectors)),
        Pose::new(V3::new(0.0, 0.0, 0.48), V3::new(1.2, 0.0, 0.0)),
    );
    // A 6 x 4 colour-patch board behind it.
    let mut rgb = Vec::new();
    for j in 0..4 {
        for i in 0..6 {
            let h = (i + 6 * j) as f32 / 24.0;
            rgb.push([
                0.15 + 0.7 * (h * 5.0).sin().abs(),
                0.15 + 0.7 * (h * 9.0).cos().abs(),
                0.15 + 0.7 * h,
            ]);
        }
    }
    let tex = Texture {
        width: 6,
        height: 4,
        rgb,
        size_m: [0.36, 0.24],
    };
    let board = Object::new(
        "patch-board",
        Shape::Rect {
            half_x_m: 0.18,
            half_y_m: 0.12,
        },
        Material::matte(Albedo::Texture(Arc::new(tex))),
        Pose::translation(0.0, 0.0, 0.56),
    );
    Ok((
        with_ambient(vec![ball, board, wall(0.6, 0.5)]),
        single_head(d),
    ))
}

fn fan(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let centre = V3::new(0.0, 0.0, 0.48);
    let mut objects = vec![Object::new(
        "hub",
        Shape::Sphere { radius_m: 0.02 },
        matte(0.3, 0.3, 0.3),
        Pose::translation(centre.x, centre.y, centre.z),
    )];
    for k in 0..4 {
        let angle = k as f64 * std::f64::consts::FRAC_PI_2;
        let rot = Pose::new(centre, V3::new(0.0, 0.0, angle));
        let blade = Pose::new(V3::new(0.07, 0.0, 0.0), V3::new(0.35, 0.0, 0.0));
        let mut o = Object::new(
            &format!("blade-{k}"),
            Shape::Cuboid {
                half_m: V3::new(0.05, 0.018, 0.002),
            },
            matte(0.8, 0.8, 0.85),
            rot * blade,
        );
        o.motion = Motion::Spin {
            centre_m: centre,
            axis: V3::z(),
            rate_rad_s: std::f64::consts::TAU * 10.0,
        };
        objects.push(o);
    }
    objects.push(wall(0.58, 0.5));
    Ok((with_ambient(objects), single_head(d)))
}

fn falling(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let mut ball = Object::new(
        "ball",
        Shape::Sphere { radius_m: 0.03 },
        matte(0.8, 0.6, 0.4),
        Pose::translation(0.0, -0.1, 0.48),
    );
    // y is down in the camera-aligned world: gravity is +y.
    ball.motion = Motion::Ballistic {
        velocity_m_s: V3::new(0.0, 0.5, 0.0),
        accel_m_s2: V3::new(0.0, 9.81, 0.0),
    };
    Ok((with_ambient(vec![ball, wall(0.58, 0.5)]), single_head(d)))
}

fn checkerboard(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let pose = Pose::new(V3::new(0.01, 0.0, 0.45), V3::new(-0.25, 0.35, 0.1));
    Ok((
        with_ambient(vec![CHECKERBOARD.object(pose), wall(0.6, 0.3)]),
        single_head(d),
    ))
}

/// The benchmark mesh: a bumpy sphere of 2 * 225 * 224 triangles, 100,352 once the 448 degenerate pole triangles are dropped.
pub fn bumpy_sphere_mesh() -> Result<Mesh, TwinError> {
    Mesh::bumpy_sphere(0.08, 225, 224, |t, p| {
        0.05 * (7.0 * t).sin() * (9.0 * p).cos() + 0.02 * (23.0 * t).cos()
    })
}

fn bumpy_mesh(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let obj = Object::new(
        "bumpy-sphere",
        Shape::Mesh(Arc::new(bumpy_sphere_mesh()?)),
        matte(0.7, 0.7, 0.7),
        Pose::translation(0.0, 0.0, 0.5),
    );
    Ok((with_ambient(vec![obj, wall(0.62, 0.4)]), single_head(d)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scene_builds_and_is_seen() {
        let detail = Detail {
            camera: (64, 48),
            projector: (96, 60),
        };
        for b in BUILT_IN {
            let (scene, rig) = (b.build)(&detail).unwrap();
            rig.validate().unwrap();
            let g = super::super::cache::CameraGeometry::new(&scene.at(0.0), &rig, 0).unwrap();
            let seen = g.depth_m.iter().filter(|d| d.is_finite()).count();
            assert!(
                seen > 64 * 48 / 2,
                "{}: only {seen} pixels see a surface",
                b.name
            );
            let lit = g.projectors[0]
                .illum
                .iter()
                .filter(|&&i| i == super::super::cache::Illum::Lit)
                .count();
            assert!(lit > 64 * 48 / 4, "{}: only {lit} pixels lit", b.name);
        }
        assert!(built_in("nope", &detail).is_err());
    }

    #[test]
    fn calibration_spheres_are_seed_001s() {
        let (scene, _) = built_in("spheres", &Detail::default()).unwrap();
        let c: Vec<V3> = scene.objects[..2]
            .iter()
            .map(|o| o.pose.translation.vector)
            .collect();
        assert!(((c[0] - c[1]).norm() - 0.1001166).abs() < 1e-12);
    }

    #[test]
    fn the_stereo_scene_is_the_sphere_scene_seen_by_two_cameras_and_one_projector() {
        let d = Detail::default();
        let (stereo, rig) = built_in("stereo-spheres", &d).unwrap();
        let (spheres, _) = built_in("spheres", &d).unwrap();
        assert_eq!(stereo.objects.len(), spheres.objects.len());
        for (a, b) in stereo.objects.iter().zip(&spheres.objects) {
            assert_eq!(a.pose, b.pose);
        }
        assert_eq!((rig.cameras.len(), rig.projectors.len()), (2, 1));
        let (l, r) = (&rig.cameras[0].model, &rig.cameras[1].model);
        let baseline =
            r.world_from_device.translation.vector - l.world_from_device.translation.vector;
        assert!((baseline - V3::new(0.17, 0.0, 0.0)).norm() < 1e-12);
        // Both cameras see both spheres' centres.
        for cam in [l, r] {
            for o in &stereo.objects[..2] {
                let p = cam.project(&o.pose.translation.vector).unwrap();
                assert!(p[0] > 0.0 && p[0] < 640.0 && p[1] > 0.0 && p[1] < 480.0);
            }
        }
    }

    #[test]
    fn bench_mesh_has_100k_triangles() {
        assert!(bumpy_sphere_mesh().unwrap().triangle_count() >= 100_000);
    }
}

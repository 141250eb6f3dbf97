//! Small rigs and scenes shared by the renderer's tests.

use super::*;

pub(super) fn camera(w: u32, h: u32, distortion: Distortion) -> Camera {
    Camera {
        name: "cam".into(),
        model: Pinhole {
            intrinsics: Intrinsics::from_fov(w, h, 40.0),
            distortion,
            world_from_device: Pose::identity(),
        },
    }
}

pub(super) fn projector(x_m: f64, w: u32, h: u32) -> Projector {
    Projector {
        name: format!("proj{x_m}"),
        model: Pinhole {
            intrinsics: Intrinsics::from_fov(w, h, 48.0),
            distortion: Distortion::default(),
            world_from_device: look_at(
                V3::new(x_m, 0.0, 0.0),
                V3::new(0.0, 0.0, 0.5),
                V3::new(0.0, -1.0, 0.0),
            ),
        },
        led_power: [1.0, 1.0, 1.0],
        defocus_sigma_px: 0.0,
        gamma: 1.0,
        reference_distance_m: 0.5,
    }
}

pub(super) fn white() -> Material {
    Material::matte(Albedo::Constant([0.8; 3]))
}

pub(super) fn tilted_plane() -> (Scene, Pose) {
    let pose = Pose::new(V3::new(0.01, -0.02, 0.5), V3::new(0.15, 0.35, 0.0));
    let scene = Scene {
        objects: vec![Object::new(
            "plane",
            Shape::Rect {
                half_x_m: 1.0,
                half_y_m: 1.0,
            },
            white(),
            pose,
        )],
        ..Default::default()
    };
    (scene, pose)
}

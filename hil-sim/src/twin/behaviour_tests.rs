//! The renderer's behaviours checked on rendered images: checkerboard
//! corners where the truth says, motion blur with mid-exposure truth,
//! colour crosstalk, and the glossy part's reflectivity range and saturation.

use std::sync::Arc;

use nalgebra::Point3;

use super::test_rig::{camera, projector, tilted_plane, white};
use super::*;

#[test]
fn checkerboard_corners_land_where_the_truth_says() {
    let detail = scenes::Detail {
        camera: (320, 240),
        projector: (320, 200),
    };
    let (scene, rig) = scenes::built_in("checkerboard", &detail).unwrap();
    let board = scenes::CHECKERBOARD;
    let pose = scene.objects[0].pose;
    let corners = board.corners_px(&pose, &rig.cameras[0].model);
    assert_eq!(corners.len(), 48);
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let k = rig.projectors[0].model.intrinsics;
    let flood = vec![ProjectorTimeline::single(
        Arc::new(Pattern::flat(k.width, k.height, 1.0)),
        0.0,
        1e-3,
    )];
    let img = r
        .frame(
            &flood,
            Exposure {
                start_s: 0.0,
                end_s: 1e-3,
            },
            &SensorModel::ideal(),
            0,
        )
        .unwrap()
        .clean;
    let at = |x: f64, y: f64| img.at(x.round() as u32, y.round() as u32, 0);
    let mut checked = 0;
    for c in corners.iter().flatten() {
        let [x, y] = *c;
        if x < 5.0 || y < 5.0 || x > 314.0 || y > 234.0 {
            continue;
        }
        // Diagonal neighbours match, adjacent ones differ strongly (dark vs light).
        let (a, b, c2, d) = (
            at(x - 3.0, y - 3.0),
            at(x + 3.0, y + 3.0),
            at(x + 3.0, y - 3.0),
            at(x - 3.0, y + 3.0),
        );
        let contrast = (a + b - c2 - d).abs() / (a + b + c2 + d);
        assert!(contrast > 0.5, "corner at {x:.1},{y:.1}: {a} {b} {c2} {d}");
        checked += 1;
    }
    assert!(checked >= 40, "only {checked} corners in view");
}

/// Renders a flood-lit ball moving at `speed_m_s` along x during a 10 ms
/// exposure (centre at x = 0 at mid-exposure).
fn moving_ball(speed_m_s: f64) -> (Frame, Rig) {
    let mut ball = Object::new(
        "ball",
        Shape::Sphere { radius_m: 0.03 },
        white(),
        Pose::translation(-speed_m_s * 0.005, 0.0, 0.4),
    );
    ball.motion = Motion::Ballistic {
        velocity_m_s: V3::new(speed_m_s, 0.0, 0.0),
        accel_m_s2: V3::zeros(),
    };
    let scene = Scene {
        objects: vec![ball],
        ..Default::default()
    };
    let rig = Rig {
        cameras: vec![camera(128, 96, Distortion::default())],
        projectors: vec![projector(0.1, 160, 120)],
        medium: Medium::Air,
    };
    let k = rig.projectors[0].model.intrinsics;
    let flood = vec![ProjectorTimeline::single(
        Arc::new(Pattern::flat(k.width, k.height, 1.0)),
        0.0,
        0.01,
    )];
    let sensor = SensorModel {
        electrons_per_unit: 2e5,
        ..SensorModel::ideal()
    };
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
    let frame = render_exposure(
        &scene,
        &rig,
        0,
        &flood,
        Exposure {
            start_s: 0.0,
            end_s: 0.01,
        },
        &sensor,
        &mut rng,
    )
    .unwrap();
    (frame, rig)
}

#[test]
fn moving_object_truth_is_at_mid_exposure_and_image_is_smeared() {
    // 2 m/s for 10 ms: 20 mm of travel, about 7 px at this scale.
    let (moving, rig) = moving_ball(2.0);
    let (still, _) = moving_ball(0.0);
    let [cx, cy] = rig.cameras[0]
        .model
        .project(&V3::new(0.0, 0.0, 0.4))
        .unwrap();
    let i = (cy.round() as usize) * 128 + cx.round() as usize;
    assert!(
        (moving.truth.depth_m()[i] as f64 - 0.37).abs() < 2e-4,
        "truth is the mid-exposure pose"
    );
    let row = cy.round() as u32;
    let partial = |f: &Frame| {
        let peak = (0..128)
            .map(|x| f.clean.at(x, row, 0))
            .fold(0.0f32, f32::max);
        (0..128)
            .filter(|&x| (0.05 * peak..0.5 * peak).contains(&f.clean.at(x, row, 0)))
            .count()
    };
    let (pm, ps) = (partial(&moving), partial(&still));
    assert!(
        pm >= ps + 6,
        "motion blur must widen the edges: {pm} vs {ps} partial pixels"
    );
}

#[test]
fn colour_crosstalk_follows_the_sensor_matrix() {
    let (scene, _) = tilted_plane();
    let rig = Rig {
        cameras: vec![camera(64, 48, Distortion::default())],
        projectors: vec![projector(0.1, 80, 60)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let red_only = vec![ProjectorTimeline {
        shown: vec![Shown {
            pattern: Arc::new(Pattern::flat(80, 60, 1.0)),
            start_s: 0.0,
            end_s: 1e-3,
            led: [1.0, 0.0, 0.0],
            display: Display::Steady,
        }],
    }];
    let m = [[0.90, 0.12, 0.03], [0.10, 0.85, 0.10], [0.03, 0.15, 0.88]];
    let sensor = SensorModel {
        channels: Channels::Rgb(m),
        electrons_per_unit: 2e6,
        ..SensorModel::ideal()
    };
    let img = r
        .frame(
            &red_only,
            Exposure {
                start_s: 0.0,
                end_s: 1e-3,
            },
            &sensor,
            0,
        )
        .unwrap()
        .clean;
    let i = (24 * 64 + 32) * 3;
    let (red, green, blue) = (
        img.data[i] as f64,
        img.data[i + 1] as f64,
        img.data[i + 2] as f64,
    );
    assert!(red > 0.05);
    assert!((green / red - 0.10 / 0.90).abs() < 1e-5 && (blue / red - 0.03 / 0.90).abs() < 1e-5);
}

#[test]
fn metal_part_spans_50_to_1_and_saturates_on_highlights() {
    let detail = scenes::Detail {
        camera: (160, 120),
        projector: (160, 100),
    };
    let (scene, rig) = scenes::built_in("metal-part", &detail).unwrap();
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let flood = vec![ProjectorTimeline::single(
        Arc::new(Pattern::flat(160, 100, 1.0)),
        0.0,
        1e-3,
    )];
    let frame = r
        .frame(
            &flood,
            Exposure {
                start_s: 0.0,
                end_s: 1e-3,
            },
            &SensorModel::mono12(),
            0,
        )
        .unwrap();
    let sat = frame.truth.saturated.iter().filter(|&&s| s).count();
    assert!(sat > 0, "specular highlights must saturate");
    assert!(sat < 160 * 120 / 4, "but not the whole part ({sat} px)");
    let albedos: Vec<f32> = (0..160 * 120)
        .filter(|&i| frame.truth.object()[i] == 0)
        .map(|i| match &scene.objects[0].material.albedo {
            Albedo::Stripes { .. } => {
                let p = frame.truth.point_m()[i];
                let local = scene.objects[0].pose.inverse_transform_point(&Point3::new(
                    p[0] as f64,
                    p[1] as f64,
                    p[2] as f64,
                ));
                scene.objects[0].material.albedo.at(&local.coords)[0]
            }
            _ => unreachable!("metal part uses stripes"),
        })
        .collect();
    let (lo, hi) = albedos
        .iter()
        .fold((f32::MAX, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi / lo >= 49.9, "reflectivity range {}:1", hi / lo);
}

#[test]
fn bad_patterns_and_timelines_are_typed_errors() {
    let (scene, _) = tilted_plane();
    let rig = Rig {
        cameras: vec![camera(32, 24, Distortion::default())],
        projectors: vec![projector(0.1, 40, 30)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let exp = Exposure {
        start_s: 0.0,
        end_s: 1e-3,
    };
    let wrong_size = vec![ProjectorTimeline::single(
        Arc::new(Pattern::flat(41, 30, 1.0)),
        0.0,
        1e-3,
    )];
    assert!(matches!(
        r.exposed(&wrong_size, exp),
        Err(TwinError::PatternSize { got_w: 41, .. })
    ));
    let short = Pattern {
        width: 40,
        height: 30,
        values: vec![0.5; 10],
    };
    let bad_buffer = vec![ProjectorTimeline::single(Arc::new(short), 0.0, 1e-3)];
    assert!(matches!(
        r.exposed(&bad_buffer, exp),
        Err(TwinError::PatternBuffer { len: 10, .. })
    ));
    assert!(matches!(
        r.exposed(&[], exp),
        Err(TwinError::TimelineCount {
            given: 0,
            expected: 1
        })
    ));
    let reversed = vec![ProjectorTimeline::single(
        Arc::new(Pattern::flat(40, 30, 1.0)),
        1e-3,
        0.0,
    )];
    assert!(matches!(
        r.exposed(&reversed, exp),
        Err(TwinError::BadInterval { .. })
    ));
    assert!(matches!(
        r.exposed(
            &[ProjectorTimeline::dark()],
            Exposure {
                start_s: 0.0,
                end_s: f64::NAN
            }
        ),
        Err(TwinError::BadInterval { .. })
    ));
    assert!(matches!(
        Renderer::new(&scene, &rig, 3, 0.0),
        Err(TwinError::NoSuchCamera { index: 3, count: 1 })
    ));
}

#[test]
fn bit_planes_sum_to_the_grey_and_a_cut_window_sees_only_its_planes() {
    let (scene, _) = tilted_plane();
    let rig = Rig {
        cameras: vec![camera(32, 24, Distortion::default())],
        projectors: vec![projector(0.1, 40, 30)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let grey = Arc::new(Pattern::from_u8(40, 30, &vec![100u8; 1200]).unwrap());
    let shown = |display| {
        vec![ProjectorTimeline {
            shown: vec![Shown {
                pattern: grey.clone(),
                start_s: 0.0,
                end_s: 1e-3,
                led: [1.0; 3],
                display,
            }],
        }]
    };
    let total = |e: &Exposed| e.per_projector[0].iter().map(|p| p[0] as f64).sum::<f64>();
    let whole = Exposure {
        start_s: 0.0,
        end_s: 1e-3,
    };
    let (steady, planes) = (
        r.exposed(&shown(Display::Steady), whole).unwrap(),
        r.exposed(&shown(Display::BitPlanes), whole).unwrap(),
    );
    assert!(
        (total(&planes) / total(&steady) - 1.0).abs() < 1e-5,
        "all 8 planes carry exactly the grey"
    );
    // 100 = 0b0110_0100: the MSB plane (first 128/255 of the interval) is dark.
    let first_half = Exposure {
        start_s: 0.0,
        end_s: 0.5e-3,
    };
    assert!(total(&r.exposed(&shown(Display::Steady), first_half).unwrap()) > 0.0);
    assert_eq!(
        total(&r.exposed(&shown(Display::BitPlanes), first_half).unwrap()),
        0.0
    );
}

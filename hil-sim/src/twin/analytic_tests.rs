//! The renderer checked against analytic answers: closed-form homography of
//! a plane, ray-sphere depth, superposition of projectors, energy of a long
//! exposure, and the Cramér-Rao bound of N-step phase noise.

use std::f64::consts::TAU;
use std::sync::Arc;

use nalgebra::{Matrix3, Point3};

use super::test_rig::{camera, projector, tilted_plane, white};
use super::*;

/// Homography from plane coordinates (s, t, 1) to the pixels of a distortion-free device.
fn plane_homography(model: &Pinhole, plane: &Pose) -> Matrix3<f64> {
    let device_from_plane = model.world_from_device.inverse() * plane;
    let r = device_from_plane.rotation.to_rotation_matrix();
    let m = r.matrix();
    let t = device_from_plane.translation.vector;
    let k = &model.intrinsics;
    let kk = Matrix3::new(k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0);
    kk * Matrix3::from_columns(&[m.column(0).into(), m.column(1).into(), t])
}

#[test]
fn plane_projector_coordinates_equal_the_homography() {
    let (scene, plane) = tilted_plane();
    let rig = Rig {
        cameras: vec![camera(160, 120, Distortion::default())],
        projectors: vec![projector(0.1, 200, 150)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let h_cam = plane_homography(&rig.cameras[0].model, &plane);
    let h_proj = plane_homography(&rig.projectors[0].model, &plane);
    let h = h_proj * h_cam.try_inverse().unwrap();
    let g = r.geometry();
    let mut worst = 0.0f64;
    let mut checked = 0;
    for y in 0..120u32 {
        for x in 0..160u32 {
            let i = (y * 160 + x) as usize;
            if g.projectors[0].illum[i] != Illum::Lit {
                continue;
            }
            let p = h * nalgebra::Vector3::new(x as f64, y as f64, 1.0);
            let uv = g.projectors[0].uv_px[i];
            worst = worst
                .max((uv[0] as f64 - p.x / p.z).abs())
                .max((uv[1] as f64 - p.y / p.z).abs());
            checked += 1;
        }
    }
    assert!(checked > 160 * 120 * 3 / 4, "only {checked} pixels lit");
    eprintln!("plane: projector coordinates vs homography, worst {worst:.2e} px over {checked} px");
    assert!(worst < 1e-3, "worst deviation {worst} px");
}

#[test]
fn sphere_depth_matches_ray_sphere_intersection() {
    // A calibration sphere of seed 001 seen through a distorted lens.
    let radius = 0.0253967;
    let centre = V3::new(0.004, -0.003, 0.3);
    let scene = Scene {
        objects: vec![Object::new(
            "sphere",
            Shape::Sphere { radius_m: radius },
            white(),
            Pose::translation(centre.x, centre.y, centre.z),
        )],
        ..Default::default()
    };
    let dist = Distortion {
        k1: -0.12,
        k2: 0.03,
        p1: 0.0004,
        p2: -0.0003,
        k3: 0.0,
    };
    let rig = Rig {
        cameras: vec![camera(128, 96, dist)],
        projectors: vec![],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let model = &rig.cameras[0].model;
    let (mut hits, mut worst) = (0, 0.0f64);
    for y in 0..96u32 {
        for x in 0..128u32 {
            let ray = model.pixel_ray(x as f64, y as f64);
            // Textbook quadratic |o + t d - c|^2 = R^2.
            let oc = ray.origin - centre;
            let b = 2.0 * ray.dir.dot(&oc);
            let c = oc.norm_squared() - radius * radius;
            let disc = b * b - 4.0 * c;
            let got = r.geometry().depth_m[(y * 128 + x) as usize];
            if disc.abs() < 1e-9 {
                continue; // grazing: either answer is right
            }
            if disc < 0.0 {
                assert!(got.is_nan(), "pixel {x},{y} should miss");
                continue;
            }
            let t = (-b - disc.sqrt()) / 2.0;
            let p = model
                .world_from_device
                .inverse_transform_point(&Point3::from(ray.at(t)));
            worst = worst.max((got as f64 - p.z).abs());
            hits += 1;
        }
    }
    assert!(hits > 500, "{hits} hits");
    eprintln!("sphere: depth vs ray-sphere, worst {worst:.2e} m over {hits} px");
    assert!(worst < 1e-7, "worst depth error {worst} m");
}

fn fringe_pattern(
    w: u32,
    h: u32,
    period_px: f64,
    angle_rad: f64,
    k: usize,
    n: usize,
) -> Arc<Pattern> {
    let f = Fringe {
        period_px,
        angle_rad,
        shift_rad: TAU * k as f64 / n as f64,
    };
    Arc::new(Pattern::fringe(w, h, &f, BitDepth::Eight))
}

#[test]
fn two_projectors_sum_to_the_single_projector_renders() {
    let (mut scene, _) = tilted_plane();
    scene.ambient_surface = [0.0; 3];
    let rig = Rig {
        cameras: vec![camera(160, 120, Distortion::default())],
        projectors: vec![projector(0.1, 200, 150), projector(-0.1, 200, 150)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let a = ProjectorTimeline::single(fringe_pattern(200, 150, 20.0, 0.0, 1, 4), 0.0, 1e-3);
    let b = ProjectorTimeline::single(fringe_pattern(200, 150, 13.0, 0.3, 2, 4), 0.0, 1e-3);
    let exp = Exposure {
        start_s: 0.0,
        end_s: 1e-3,
    };
    let both = r.exposed(&[a.clone(), b.clone()], exp).unwrap();
    let only_a = r.exposed(&[a, ProjectorTimeline::dark()], exp).unwrap();
    let only_b = r.exposed(&[ProjectorTimeline::dark(), b], exp).unwrap();
    let sum: Vec<[f32; 3]> = only_a
        .total()
        .iter()
        .zip(only_b.total())
        .map(|(x, y)| [0, 1, 2].map(|c| x[c] + y[c]))
        .collect();
    assert_eq!(both.total(), sum, "linear exposures must add exactly");
    let sensor = SensorModel {
        electrons_per_unit: 2e6,
        ..SensorModel::ideal()
    };
    let img = |e: &Exposed| sensor.expose(160, 120, &e.total(), None).0;
    let (ib, ia, ibb) = (img(&both), img(&only_a), img(&only_b));
    let worst = ib
        .data
        .iter()
        .zip(ia.data.iter().zip(&ibb.data))
        .map(|(s, (x, y))| (s - (x + y)).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-6, "noise-free sensor images differ by {worst}");
    let truth = r
        .frame(
            &[ProjectorTimeline::dark(), ProjectorTimeline::dark()],
            exp,
            &sensor,
            1,
        )
        .unwrap()
        .truth;
    assert!(
        truth.overlap().iter().filter(|&&o| o).count() > 1000,
        "the heads must overlap"
    );
}

#[test]
fn long_exposure_energy_is_the_sum_of_displayed_patterns() {
    // Seed 001: 24 binary patterns at 5 kHz inside one 4.8 ms exposure.
    let (scene, _) = tilted_plane();
    let rig = Rig {
        cameras: vec![camera(128, 96, Distortion::default())],
        projectors: vec![projector(0.1, 160, 120)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let period_s = 200e-6;
    let items: Vec<(Arc<Pattern>, [f32; 3])> = (0..24)
        .map(|m| {
            let f = Fringe {
                period_px: 18.0 + m as f64,
                angle_rad: 0.13 * m as f64,
                shift_rad: 0.0,
            };
            let led = [
                (m % 3 == 0) as u8 as f32,
                (m % 3 == 1) as u8 as f32,
                (m % 3 == 2) as u8 as f32,
            ];
            (Arc::new(Pattern::fringe(160, 120, &f, BitDepth::One)), led)
        })
        .collect();
    let tl = ProjectorTimeline::sequence(items.clone(), 1e-3, period_s);
    let long = r
        .exposed(
            std::slice::from_ref(&tl),
            Exposure {
                start_s: 1e-3,
                end_s: 1e-3 + 24.0 * period_s,
            },
        )
        .unwrap();
    let mut sum = vec![[0.0f64; 3]; 128 * 96];
    for s in &tl.shown {
        let one = r
            .exposed(
                std::slice::from_ref(&tl),
                Exposure {
                    start_s: s.start_s,
                    end_s: s.end_s,
                },
            )
            .unwrap();
        for (a, p) in sum.iter_mut().zip(&one.per_projector[0]) {
            (0..3).for_each(|c| a[c] += p[c] as f64);
        }
    }
    let rel = |x: &[[f32; 3]], y: &[[f64; 3]]| {
        let num: f64 = x
            .iter()
            .zip(y)
            .map(|(a, b)| (0..3).map(|c| (a[c] as f64 - b[c]).abs()).sum::<f64>())
            .sum();
        let den: f64 = y.iter().map(|b| b.iter().sum::<f64>()).sum();
        num / den
    };
    assert!(rel(&long.per_projector[0], &sum) < 1e-5);
    // A 50 us trigger delay: the first pattern is seen for 150 us only and
    // the tail of the window sees a dark DMD.
    let late = r
        .exposed(
            std::slice::from_ref(&tl),
            Exposure {
                start_s: 1e-3 + 50e-6,
                end_s: 1e-3 + 50e-6 + 24.0 * period_s,
            },
        )
        .unwrap();
    let first = r
        .exposed(
            std::slice::from_ref(&tl),
            Exposure {
                start_s: 1e-3,
                end_s: 1e-3 + period_s,
            },
        )
        .unwrap();
    let expect: Vec<[f64; 3]> = sum
        .iter()
        .zip(&first.per_projector[0])
        .map(|(s, f)| [0, 1, 2].map(|c| s[c] - 0.25 * f[c] as f64))
        .collect();
    assert!(rel(&late.per_projector[0], &expect) < 1e-5);
    assert!(
        rel(&late.per_projector[0], &sum) > 1e-3,
        "a timing error must show"
    );
}

fn wrap(x: f64) -> f64 {
    (x + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI
}

/// N-step phase and modulation (DESIGN.md convention) of pixel i.
fn phase_and_modulation(frames: &[Image], i: usize) -> (f64, f64, f64) {
    let n = frames.len();
    let (mut s, mut c, mut m) = (0.0, 0.0, 0.0);
    for (k, f) in frames.iter().enumerate() {
        let d = TAU * k as f64 / n as f64;
        let v = f.data[i] as f64;
        s += v * d.sin();
        c += v * d.cos();
        m += v;
    }
    (
        (-s).atan2(c),
        2.0 / n as f64 * (s * s + c * c).sqrt(),
        m / n as f64,
    )
}

#[test]
fn phase_noise_meets_the_cramer_rao_bound() {
    let (scene, _) = tilted_plane();
    let rig = Rig {
        cameras: vec![camera(160, 120, Distortion::default())],
        projectors: vec![projector(0.1, 200, 150)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let sensor = SensorModel::mono12();
    let n = 4;
    let exposure = Exposure {
        start_s: 0.0,
        end_s: 5e-4,
    };
    let frames: Vec<Frame> = (0..n)
        .map(|k| {
            let tl =
                ProjectorTimeline::single(fringe_pattern(200, 150, 16.0, 0.0, k, n), 0.0, 5e-4);
            r.frame(&[tl], exposure, &sensor, 100 + k as u64).unwrap()
        })
        .collect();
    let noisy: Vec<Image> = frames.iter().map(|f| f.image.clone()).collect();
    let clean: Vec<Image> = frames.iter().map(|f| f.clean.clone()).collect();
    let truth = frames[0].truth.absolute_phase(
        0,
        &Fringe {
            period_px: 16.0,
            angle_rad: 0.0,
            shift_rad: 0.0,
        },
    );
    let top = frames
        .iter()
        .flat_map(|f| f.clean.data.iter())
        .fold(0.0f32, |a, &b| a.max(b));
    assert!(
        !frames.iter().any(|f| f.truth.saturated.iter().any(|&s| s)),
        "test needs an unsaturated image, max {top}"
    );
    let (mut z2, mut count, mut sys) = (0.0, 0usize, 0.0f64);
    for i in 0..160 * 120 {
        if truth[i].is_nan() {
            continue;
        }
        let (phi_clean, b, a) = phase_and_modulation(&clean, i);
        let (phi_noisy, _, _) = phase_and_modulation(&noisy, i);
        let sigma_i = sensor.output_sigma(a * sensor.full_well_e / sensor.gain);
        let crb = sigma_i * (2.0 / n as f64).sqrt() / b;
        z2 += (wrap(phi_noisy - phi_clean) / crb).powi(2);
        sys = sys.max(wrap(phi_clean - truth[i] as f64).abs());
        count += 1;
    }
    let ratio = (z2 / count as f64).sqrt();
    assert!(count > 10_000);
    eprintln!("N-step phase noise: measured / CRB sigma = {ratio:.4} over {count} px; systematic {sys:.5} rad");
    assert!(
        (ratio - 1.0).abs() < 0.10,
        "measured/CRB sigma ratio {ratio}"
    );
    // The noise-free chain returns the true absolute phase (wrapped).
    assert!(sys < 0.02, "systematic phase error {sys} rad");
}

#[test]
fn triangulating_true_projector_columns_gives_true_depth() {
    // What a reconstruction does with a perfect absolute phase: intersect
    // the camera ray with the plane of projector column u. With a
    // distortion-free projector that plane is exact.
    let scene = Scene {
        objects: vec![Object::new(
            "sphere",
            Shape::Sphere { radius_m: 0.05 },
            white(),
            Pose::translation(0.0, 0.0, 0.45),
        )],
        ..Default::default()
    };
    let dist = Distortion {
        k1: -0.1,
        k2: 0.02,
        p1: 0.0003,
        p2: 0.0,
        k3: 0.0,
    };
    let rig = Rig {
        cameras: vec![camera(128, 96, dist)],
        projectors: vec![projector(0.1, 200, 150)],
        medium: Medium::Air,
    };
    let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
    let g = r.geometry();
    let (cam, proj) = (&rig.cameras[0].model, &rig.projectors[0].model);
    let k = proj.intrinsics;
    let (mut worst, mut n) = (0.0f64, 0);
    for y in 0..96u32 {
        for x in 0..128u32 {
            let i = (y * 128 + x) as usize;
            if g.projectors[0].illum[i] != Illum::Lit {
                continue;
            }
            let u = g.projectors[0].uv_px[i][0] as f64;
            // Plane through the projector centre spanned by its y axis and the ray to (u, cy).
            let rot = proj.world_from_device.rotation;
            let a = rot * V3::new((u - k.cx) / k.fx, 0.0, 1.0);
            let normal = a.cross(&(rot * V3::y())).normalize();
            let ray = cam.pixel_ray(x as f64, y as f64);
            let t = (proj.centre() - ray.origin).dot(&normal) / ray.dir.dot(&normal);
            let z = cam
                .world_from_device
                .inverse_transform_point(&Point3::from(ray.at(t)))
                .z;
            worst = worst.max((z - g.depth_m[i] as f64).abs());
            n += 1;
        }
    }
    eprintln!(
        "triangulation from true projector columns: worst depth error {worst:.2e} m over {n} px"
    );
    assert!(n > 1000);
    // f32 storage of u (about 1e-5 px at 200 px) bounds this, not the geometry.
    assert!(worst < 2e-6, "worst {worst} m");
}

#[test]
fn projector_gamma_harmonics_hurt_3_step_but_not_4_step() {
    // (0.5 + 0.5 cos)^2.2 is mostly a 2nd harmonic: N = 3 aliases it onto
    // the fundamental, N = 4 rejects it (only 3rd/5th would alias).
    let (scene, _) = tilted_plane();
    let fringe = Fringe {
        period_px: 24.0,
        angle_rad: 0.0,
        shift_rad: 0.0,
    };
    let rms_error = |gamma: f64, n: usize| {
        let mut p = projector(0.1, 200, 150);
        p.gamma = gamma;
        let rig = Rig {
            cameras: vec![camera(96, 72, Distortion::default())],
            projectors: vec![p],
            medium: Medium::Air,
        };
        let r = Renderer::new(&scene, &rig, 0, 0.0).unwrap();
        let sensor = SensorModel {
            electrons_per_unit: 2e6,
            ..SensorModel::ideal()
        };
        let exp = Exposure {
            start_s: 0.0,
            end_s: 1e-3,
        };
        let frames: Vec<Image> = (0..n)
            .map(|k| {
                let tl =
                    ProjectorTimeline::single(fringe_pattern(200, 150, 24.0, 0.0, k, n), 0.0, 1e-3);
                r.frame(&[tl], exp, &sensor, 0).unwrap().clean
            })
            .collect();
        let truth = r
            .frame(&[ProjectorTimeline::dark()], exp, &sensor, 0)
            .unwrap()
            .truth
            .absolute_phase(0, &fringe);
        let errs: Vec<f64> = (0..96 * 72)
            .filter(|&i| truth[i].is_finite())
            .map(|i| wrap(phase_and_modulation(&frames, i).0 - truth[i] as f64))
            .collect();
        (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt()
    };
    let (lin3, gam3, gam4) = (rms_error(1.0, 3), rms_error(2.2, 3), rms_error(2.2, 4));
    eprintln!("phase error rms: 3-step gamma 1 {lin3:.4}, 3-step gamma 2.2 {gam3:.4}, 4-step gamma 2.2 {gam4:.4} rad");
    assert!(lin3 < 0.01, "{lin3}");
    assert!(gam3 > 0.1, "{gam3}");
    assert!(gam4 < 0.02, "{gam4}");
}

#[test]
fn pixel_samples_give_an_edge_pixel_the_grey_level_of_its_area_share() {
    // A fronto-parallel plane 0.5 m away, light (0.8) left of x = 1.3 mm, dark (0.2)
    // right of it, lit by ambient only: the edge crosses each row at a known column.
    let (w, h) = (64u32, 48u32);
    let edge_x_m = 0.0013;
    let scene = Scene {
        objects: vec![Object::new(
            "edge",
            Shape::Rect {
                half_x_m: 1.0,
                half_y_m: 1.0,
            },
            Material::matte(Albedo::Stripes {
                period_m: 1.0,
                colours: vec![[0.2; 3], [0.8; 3]],
            }),
            Pose::translation(edge_x_m, 0.0, 0.5),
        )],
        ambient_surface: [1.0; 3],
        ambient_direct: [0.0; 3],
    };
    let rig = Rig {
        cameras: vec![camera(w, h, Distortion::default())],
        projectors: vec![projector(0.1, 200, 150)],
        medium: Medium::Air,
    };
    let k = &rig.cameras[0].model.intrinsics;
    let edge_px = k.cx + k.fx * edge_x_m / 0.5;
    let exp = Exposure {
        start_s: 0.0,
        end_s: 1.0,
    };
    // Edge column estimated from the grey level of the one pixel it crosses.
    let edge_from = |samples: u32| -> (f64, usize) {
        let r = Renderer::with_pixel_samples(&scene, &rig, 0, 0.0, samples).unwrap();
        assert_eq!(r.pixel_samples(), samples);
        let e = r.exposed(&[ProjectorTimeline::dark()], exp).unwrap();
        let y = h as usize / 2;
        let row: Vec<f64> = (0..w as usize)
            .map(|x| f64::from(e.ambient[y * w as usize + x][0]))
            .collect();
        let mixed = row.iter().filter(|v| (0.21..0.79).contains(*v)).count();
        let x = edge_px.round() as usize;
        // Light share of pixel x = 0.8 f + 0.2 (1 - f); the edge sits f into it.
        let f = (row[x] - 0.2) / 0.6;
        (x as f64 - 0.5 + f, mixed)
    };
    let (one, mixed_one) = edge_from(1);
    let (eight, mixed_eight) = edge_from(8);
    eprintln!("edge at {edge_px:.4} px: 1 sample {one:.4} px, 8x8 samples {eight:.4} px");
    // One ray per pixel: no grey pixels, the edge snaps to a pixel boundary.
    assert_eq!(mixed_one, 0);
    assert!((one - edge_px).abs() > 0.1, "{one} vs {edge_px}");
    // 8 x 8 samples: the area share, to the sample grid's 1/16 px.
    assert_eq!(mixed_eight, 1);
    assert!(
        (eight - edge_px).abs() <= 1.0 / 16.0 + 1e-6,
        "{eight} vs {edge_px}"
    );
    // Nonsense sample counts are refused.
    assert!(matches!(
        Renderer::with_pixel_samples(&scene, &rig, 0, 0.0, 0),
        Err(TwinError::BadParameter { .. })
    ));
}

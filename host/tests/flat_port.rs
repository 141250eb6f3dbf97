//! Triangulation through flat ports against the DIGITAL TWIN (issue 18). A matte plane
//! under water (turbidity T1, so the fringes stay clean) is rendered by the twin, whose
//! camera and projector look through thin flat ports 30 mm in front of them; the frames
//! are decoded by the usual pipeline (`Reconstructor`: 4-step phase, heterodyne
//! unwrapping) and each valid pixel is triangulated twice: with the in-air pinhole
//! models (the pipeline's own points) and through the ports
//! (`triangulation::flat_port`). Depth errors against the twin's true depth, at three
//! distances; run with `cargo test -p slscan --test flat_port -- --nocapture`.

use std::f64::consts::TAU;
use std::sync::Arc;

use hil_sim::twin::scenes::{single_head, Detail};
use hil_sim::twin::{
    Albedo, BitDepth, Exposure, Fringe, Material, Medium, Object, Pattern, Pose, ProjectorTimeline,
    Renderer, Rig, Scene, SensorModel, Shape, Turbidity, Water, V3,
};
use nalgebra::{Point3, Vector3};
use slscan::raster::Raster;
use slscan::reconstruct::{ReconstructConfig, Reconstruction, Reconstructor};
use slscan::sim::calibration::from_twin::head_from_twin;
use slscan::triangulation::flat_port::{FlatPort, PortTriangulator};
use slscan::unwrap::PixelStatus;

/// Small renders keep the test quick on 2 cores.
const DETAIL: Detail = Detail {
    camera: (320, 240),
    projector: (640, 400),
};
const STEPS: usize = 4;
/// Heterodyne periods, DMD pixels, finest first (beat 1320 px > the 640 px DMD).
const PERIODS: [f64; 3] = [20.0, 22.0, 24.0];
/// The twin's ports (as in `hil-sim dataset underwater`), metres in front of each device.
const PORT_DISTANCE_M: f64 = 0.03;
/// Plane distances from the camera, metres.
const DISTANCES_M: [f64; 3] = [0.35, 0.5, 0.7];
/// In air, 0.7 ms gives about 5600 e- on a white patch at 0.5 m (full well 10 ke-).
const AIR_EXPOSURE_S: f64 = 0.7e-3;

/// The twin's water at T1 behind thin ports `PORT_DISTANCE_M` in front of each device.
fn water() -> Water {
    Water::preset(Turbidity::T1, PORT_DISTANCE_M)
}

/// A matte plane centred `z_m` in front of the camera, tilted like the built-in `plane`.
fn plane_at(z_m: f64) -> Scene {
    Scene {
        objects: vec![Object::new(
            "plane",
            Shape::Rect {
                half_x_m: 0.6,
                half_y_m: 0.6,
            },
            Material::matte(Albedo::Constant([0.8; 3])),
            Pose::new(V3::new(0.0, 0.0, z_m), V3::new(0.2, 0.3, 0.0)),
        )],
        ambient_surface: [0.05; 3],
        ambient_direct: [0.01; 3],
    }
}

/// Exposure that keeps the plane near the in-air signal at 0.5 m: the projector's
/// inverse-square falloff and the green attenuation over the round trip made up.
fn exposure_at(z_m: f64) -> Exposure {
    let c = water().attenuation_per_m[1];
    Exposure {
        start_s: 0.0,
        end_s: AIR_EXPOSURE_S * (z_m / 0.5).powi(2) * (c * 2.0 * z_m).exp(),
    }
}

/// Per-pixel depth errors at one distance, metres, over the pixels every method gave.
#[derive(Default)]
struct Errors {
    /// The pipeline's own points: in-air models, mono12 frames.
    in_air: Vec<f64>,
    /// Through the ports, phase decoded from the mono12 frames.
    port_decoded: Vec<f64>,
    /// Through the ports, phase decoded from noise-free frames (what is not noise).
    port_noise_free: Vec<f64>,
    /// Through the ports, from noise-free frames rendered without the forward-scatter blur.
    port_no_scatter: Vec<f64>,
    /// Through the ports, with the twin's true projector column.
    port_true_column: Vec<f64>,
}

fn rms(e: &[f64]) -> f64 {
    (e.iter().map(|e| e * e).sum::<f64>() / e.len() as f64).sqrt()
}

fn mean(e: &[f64]) -> f64 {
    e.iter().sum::<f64>() / e.len() as f64
}

/// `STEPS` column-fringe frames per period, in `Reconstructor` order.
fn fringe_frames(
    renderer: &Renderer,
    exposure: Exposure,
    sensor: &SensorModel,
) -> Vec<Raster<f32>> {
    let (w, h) = DETAIL.projector;
    let mut frames = Vec::new();
    for (k, &period_px) in PERIODS.iter().enumerate() {
        for n in 0..STEPS {
            let fringe = Fringe {
                period_px,
                angle_rad: 0.0,
                shift_rad: TAU * n as f64 / STEPS as f64,
            };
            let (image, _) = renderer
                .image(
                    &timeline(Pattern::fringe(w, h, &fringe, BitDepth::Eight), exposure),
                    exposure,
                    sensor,
                    (k * STEPS + n) as u64,
                )
                .unwrap();
            let (iw, ih) = (image.width as usize, image.height as usize);
            frames.push(Raster::from_vec(iw, ih, image.data).unwrap());
        }
    }
    frames
}

fn timeline(pattern: Pattern, exposure: Exposure) -> Vec<ProjectorTimeline> {
    vec![ProjectorTimeline::single(
        Arc::new(pattern),
        0.0,
        exposure.end_s,
    )]
}

/// The camera's renderer of the plane at `z_m` under `water`, and the rig.
fn renderer(z_m: f64, water: Water) -> (Renderer, Rig) {
    let mut rig = single_head(&DETAIL);
    rig.medium = Medium::Water(water);
    (Renderer::new(&plane_at(z_m), &rig, 0, 0.0).unwrap(), rig)
}

fn errors_at(z_m: f64) -> Errors {
    let (renderer, rig) = renderer(z_m, water());
    let exposure = exposure_at(z_m);
    let (w, h) = DETAIL.projector;
    let truth = renderer
        .frame(
            &timeline(Pattern::flat(w, h, 0.5), exposure),
            exposure,
            &SensorModel::ideal(),
            0,
        )
        .unwrap()
        .truth;
    // The rig's true devices, in the camera frame.
    let head = head_from_twin(&rig, 0, 0, "A").unwrap();
    let mut config = ReconstructConfig::new(PERIODS.to_vec());
    config.noise_sigma = SensorModel::mono12().output_sigma(3000.0) as f32;
    config.normals = false;
    let reconstructor = Reconstructor::from_head(&head, config).unwrap();
    let decode = |renderer: &Renderer, sensor: SensorModel| {
        let frames = fringe_frames(renderer, exposure, &sensor);
        let refs: Vec<&Raster<f32>> = frames.iter().collect();
        reconstructor.reconstruct(&refs, None).unwrap()
    };
    let noisy = decode(&renderer, SensorModel::mono12());
    let clean = decode(&renderer, SensorModel::ideal());
    let unblurred = decode(
        &self::renderer(
            z_m,
            Water {
                forward_sigma_px_per_m: 0.0,
                ..water()
            },
        )
        .0,
        SensorModel::ideal(),
    );
    // The twin's true head carries its ports.
    let port = FlatPort::thin(PORT_DISTANCE_M, water().refractive_index).unwrap();
    assert_eq!(head.port, Some(port));
    let tri = PortTriangulator::new(&head.camera, &port, &head.projector, &port).unwrap();

    // Absolute phase of the finest period -> projector column, as the pipeline does.
    let px_per_rad = PERIODS[0] / TAU;
    let through = |rec: &Reconstruction| {
        let columns: Vec<f32> = rec
            .pixels
            .phase_u
            .iter()
            .map(|&p| (f64::from(p) * px_per_rad) as f32)
            .collect();
        tri.intersect_columns(&columns).unwrap()
    };
    let true_columns: Vec<f32> = truth.projector_uv_px(0).iter().map(|uv| uv[0]).collect();
    let [through_noisy, through_clean, through_unblurred] =
        [&noisy, &clean, &unblurred].map(through);
    let through_true = tri.intersect_columns(&true_columns).unwrap();
    let mut e = Errors::default();
    for i in 0..true_columns.len() {
        let want = f64::from(truth.depth_m()[i]);
        let valid = [&noisy, &clean, &unblurred]
            .iter()
            .all(|r| r.pixels.status[i] == PixelStatus::Valid);
        if !valid || truth.saturated[i] || !want.is_finite() {
            continue;
        }
        let hits = [
            through_noisy[i],
            through_clean[i],
            through_unblurred[i],
            through_true[i],
        ];
        let [Some(a), Some(b), Some(c), Some(d)] = hits else {
            continue;
        };
        e.in_air.push(f64::from(noisy.pixels.depth_m[i]) - want);
        e.port_decoded.push(a.depth_m - want);
        e.port_noise_free.push(b.depth_m - want);
        e.port_no_scatter.push(c.depth_m - want);
        e.port_true_column.push(d.depth_m - want);
    }
    e
}

#[test]
fn the_port_model_bends_rays_as_the_twin_does() {
    let twin = water();
    let port = FlatPort::thin(twin.port_distance_m, twin.refractive_index).unwrap();
    for d in [
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.3, -0.2, 1.0),
        Vector3::new(-0.6, 0.45, 1.0),
    ] {
        let d = d.normalize();
        let ours = port.refract_out(&d).unwrap();
        let theirs = twin.refract_out(&d).unwrap();
        assert!((ours.origin_m.coords - theirs.origin).norm() < 1e-15);
        assert!((ours.direction - theirs.dir).norm() < 1e-15);
        // Aiming back at a water point lands on the twin's port crossing.
        let p = theirs.at(0.5);
        let crossing = twin.port_crossing(&p).unwrap();
        let aim = port.aim(&Point3::from(p)).unwrap();
        assert!(
            (aim - crossing.normalize()).norm() < 1e-12,
            "{aim} vs {crossing}"
        );
    }
}

#[test]
fn a_plane_under_water_is_far_more_accurate_through_the_ports_than_in_air() {
    println!(
        "plane under water (twin, T1, thin ports {:.0} mm in front of camera and projector, \
         n = {}), depth error against the twin's truth, mm:",
        PORT_DISTANCE_M * 1e3,
        water().refractive_index
    );
    println!(
        "| plane at | pixels | in air: mean / RMSE | through the ports: mean / RMSE | \
         same, noise-free frames | same, noise-free, no forward scatter | same, true columns |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    for &z_m in &DISTANCES_M {
        let e = errors_at(z_m);
        let mm = |f: fn(&[f64]) -> f64, v: &[f64]| f(v) * 1e3;
        let row = (
            e.in_air.len(),
            [mm(mean, &e.in_air), mm(rms, &e.in_air)],
            [mm(mean, &e.port_decoded), mm(rms, &e.port_decoded)],
            mm(rms, &e.port_noise_free),
            mm(rms, &e.port_no_scatter),
            mm(rms, &e.port_true_column),
        );
        println!(
            "| {:.2} m | {} | {:+.2} / {:.2} | {:+.4} / {:.4} | {:.4} | {:.4} | {:.6} |",
            z_m, row.0, row.1[0], row.1[1], row.2[0], row.2[1], row.3, row.4, row.5
        );
        rows.push(row);
    }
    for (&z_m, &(n, [_, in_air], [port_mean, port], _, no_scatter, true_column)) in
        DISTANCES_M.iter().zip(&rows)
    {
        assert!(n > 320 * 240 / 4, "{z_m} m: only {n} pixels");
        // The model is the twin's geometry: exact up to the f32 truth.
        assert!(
            true_column < 1e-3,
            "{z_m} m: {true_column} mm with true columns"
        );
        // Without noise and blur, decoding leaves little (8-bit patterns, defocus).
        assert!(
            no_scatter < 0.05,
            "{z_m} m: {no_scatter} mm without noise or scatter"
        );
        // With noise and scatter: under a millimetre, nearly unbiased.
        assert!(port < 1.0, "{z_m} m: {port} mm through the ports");
        assert!(
            port_mean.abs() < 0.25 * port,
            "{z_m} m: mean {port_mean} mm"
        );
        // In air: centimetres, at least 20 times worse.
        assert!(
            in_air > 20.0 * port,
            "{z_m} m: in air {in_air} mm vs {port} mm"
        );
    }
}

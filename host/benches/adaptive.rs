//! Prints a table: the host's adaptation step of adaptive projection
//! (seed 003): 7 floods and the full-intensity set's reconstruction in, the
//! exposure and 12 adapted DMD patterns out, at a 640x480 camera with a
//! 1280x800 DMD and at 3072x2048 with a 1920x1080 DMD. The scene is a
//! plane with a saturated highlight disc (a quarter of the pixels lowered,
//! a tenth mapped by homography); stage times from separate calls. Then
//! seed 004's colour step at the same sizes: the Gray-code matching decode
//! and the adaptation to 9 colour images of three planes.
//!
//! `cargo bench -p slscan --bench adaptive`

use std::time::Instant;

use nalgebra::Point3;
use slscan::adaptive::colour::{
    adapt_colour, decode_matching, matching_patterns, ColourParams, ColourResponse,
};
use slscan::adaptive::fringes::adapted_fringes;
use slscan::adaptive::hdr::{adapt, HdrParams, PatternTarget, FLOOD_LEVELS};
use slscan::adaptive::mapping::{fill_clusters, from_points};
use slscan::adaptive::projector_map::{footprint_px, projector_levels};
use slscan::adaptive::response::fit_response;
use slscan::calibration::PinholeModel;
use slscan::raster::Raster;
use slscan::reconstruct::PixelMaps;
use slscan::unwrap::PixelStatus;

/// The floods and the decoded points of a plane 0.5 m away with a
/// highlight disc of a fifth of the image height (saturated, no phase).
fn scene(
    camera_px: (usize, usize),
    dmd_px: (u32, u32),
) -> (Vec<Raster<f32>>, PixelMaps, PinholeModel) {
    let (w, h) = camera_px;
    let camera = PinholeModel::ideal(w as u32, h as u32, 1.2 * w as f64);
    let mut projector = PinholeModel::ideal(dmd_px.0, dmd_px.1, 1.3 * f64::from(dmd_px.0));
    projector.pose.translation_m.x = -0.05;
    let (cx, cy, r) = (w as f64 * 0.4, h as f64 * 0.5, h as f64 * 0.2);
    let highlight = |x: usize, y: usize| {
        let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt() / (2.0 * r);
        (8.0 * (-d * d * 4.0).exp()) as f32
    };
    let floods = FLOOD_LEVELS
        .iter()
        .map(|&l| Raster::from_fn(w, h, |x, y| (0.02 + (0.4 + highlight(x, y)) * l).min(1.0)))
        .collect();
    let mut maps = PixelMaps {
        width: w,
        height: h,
        status: vec![PixelStatus::Valid; w * h],
        phase_u: vec![0.0; w * h],
        point_m: [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]],
        depth_m: vec![0.5; w * h],
        sigma_m: vec![1e-5; w * h],
        modulation: vec![0.2; w * h],
        background: vec![0.2; w * h],
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let ray = camera.pixel_ray(x as f64, y as f64).expect("ray");
            let p: Point3<f64> = ray.origin_m + ray.direction * (0.5 / ray.direction.z);
            for k in 0..3 {
                maps.point_m[k][i] = p[k] as f32;
            }
            if ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt() < r {
                maps.status[i] = PixelStatus::Masked;
            }
        }
    }
    (floods, maps, projector)
}

/// Seed 004's inputs for the same plane: the five floods' response (a red
/// half and a white half) and the matching frames a one-to-one view of
/// the DMD's centre would give.
fn colour_inputs(
    camera_px: (usize, usize),
    dmd_px: (u32, u32),
    block_px: u32,
) -> (ColourResponse, Vec<Raster<f32>>) {
    let (w, h) = camera_px;
    let response = ColourResponse {
        offset: Raster::filled(w, h, 0.03),
        band_gain: [
            Raster::filled(w, h, 0.3),
            Raster::from_fn(w, h, |x, _| if x < w / 2 { 0.02 } else { 0.3 }),
            Raster::from_fn(w, h, |x, _| if x < w / 2 { 0.02 } else { 0.3 }),
        ],
        white_gain: Raster::from_fn(w, h, |x, _| if x < w / 2 { 0.34 } else { 0.9 }),
    };
    let frames = matching_patterns(dmd_px, block_px)
        .iter()
        .map(|p| {
            Raster::from_fn(w, h, |x, y| {
                let u = (x * dmd_px.0 as usize / w).min(dmd_px.0 as usize - 1);
                let v = (y * dmd_px.1 as usize / h).min(dmd_px.1 as usize - 1);
                0.03 + 0.6 * p.data[v * dmd_px.0 as usize + u]
            })
        })
        .collect();
    (response, frames)
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let params = HdrParams::default();
    let periods = slscan::scan::default_periods_px(1280);
    println!(
        "adaptive projection, host step (floods + reconstruction in, 12 patterns out), {} rayon threads",
        rayon::current_num_threads()
    );
    println!("| camera | DMD | whole step | response fit | mapping (+ homographies) | DMD level map | 12 patterns | lowered px | by homography |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (camera_px, dmd_px) in [((640, 480), (1280, 800)), ((3072, 2048), (1920, 1080))] {
        let (floods, maps, projector) = scene(camera_px, dmd_px);
        let refs: Vec<&Raster<f32>> = floods.iter().collect();
        let runs = 3;
        let mut whole = f64::INFINITY;
        let mut result = None;
        for _ in 0..runs {
            let t = Instant::now();
            let target = PatternTarget {
                projector: &projector,
                dmd_px,
                periods_px: &periods,
                steps: 4,
            };
            let a = adapt(&refs, &maps, target, 0.15, &params).expect("adapts");
            whole = whole.min(ms(t));
            result = Some(a);
        }
        let a = result.expect("ran");
        let t = Instant::now();
        let _ = fit_response(&refs, &params.levels, params.saturation).expect("fits");
        let fit_ms = ms(t);
        let t = Instant::now();
        let mut uv = from_points(&maps, &projector);
        let needs = Raster {
            width: uv.width,
            height: uv.height,
            data: a.camera_levels.data.iter().map(|l| l.is_finite()).collect(),
        };
        let footprint = footprint_px(&uv);
        fill_clusters(
            &mut uv,
            &needs,
            params.ring_px,
            params.max_homography_rms_px,
        );
        let map_ms = ms(t);
        let t = Instant::now();
        let levels = projector_levels(&uv, &a.camera_levels, dmd_px, footprint, params.grow_px);
        let level_ms = ms(t);
        let t = Instant::now();
        let _ = adapted_fringes(&levels, params.fringe_floor, &periods, 4);
        let pattern_ms = ms(t);
        println!(
            "| {}x{} | {}x{} | {whole:.0} ms | {fit_ms:.0} ms | {map_ms:.0} ms | {level_ms:.0} ms | {pattern_ms:.0} ms | {} | {} |",
            camera_px.0,
            camera_px.1,
            dmd_px.0,
            dmd_px.1,
            a.stats.lowered_px,
            a.stats.mapped_by_homography_px
        );
    }
    println!();
    println!("seed 004's colour step (68 matching images + 5 floods in, 9 colour images of 3 planes out)");
    println!("| camera | DMD | matching decode | adaptation (exposure, levels, 27 planes) |");
    println!("|---|---|---|---|");
    let colour = ColourParams::default();
    for (camera_px, dmd_px) in [((640, 480), (1280, 800)), ((3072, 2048), (1920, 1080))] {
        let (response, frames) = colour_inputs(camera_px, dmd_px, colour.block_px);
        let t = Instant::now();
        let uv = decode_matching(&frames, &response, dmd_px, &colour).expect("decodes");
        let decode_ms = ms(t);
        drop(frames);
        let t = Instant::now();
        let a = adapt_colour(&response, &uv, dmd_px, &periods, 3, 0.15, &colour).expect("adapts");
        let adapt_ms = ms(t);
        assert_eq!(a.patterns.len(), 27);
        println!(
            "| {}x{} | {}x{} | {decode_ms:.0} ms | {adapt_ms:.0} ms |",
            camera_px.0, camera_px.1, dmd_px.0, dmd_px.1
        );
    }
}

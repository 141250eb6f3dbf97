//! Decoded projector coordinates + a calibrated head -> the organised result and cloud
//! (columns: camera ray / projector plane; columns and rows: the two rays' closest
//! point), with each point's predicted noise from its coordinate noise.

use rayon::prelude::*;

use super::decode::AxisCoordinates;
use super::{CaptureError, ProjectorAxis};
use crate::calibration::Head;
use crate::reconstruct::{PixelMaps, Reconstruction};
use crate::simd::Simd;
use crate::triangulation::Triangulator;
use crate::unwrap::PixelStatus;

/// Triangulates `axes` (from [`super::decode::decode`]) with `head`; normals when asked.
pub fn triangulate(
    head: &Head,
    axes: &[AxisCoordinates],
    normals: bool,
) -> Result<Reconstruction, CaptureError> {
    let columns = axes.iter().find(|a| a.axis == ProjectorAxis::Column);
    let rows = axes.iter().find(|a| a.axis == ProjectorAxis::Row);
    let main = columns.or(rows).ok_or(CaptureError::NoAxis)?;
    let expected = (
        head.camera.width_px as usize,
        head.camera.height_px as usize,
    );
    if main.coord_px.size() != expected {
        return Err(CaptureError::CameraSize {
            expected,
            got: main.coord_px.size(),
        });
    }
    let triangulator = Triangulator::new(&head.camera, &head.projector);
    let (width, height) = expected;
    let n = width * height;
    let mut maps = PixelMaps {
        width,
        height,
        status: vec![PixelStatus::Masked; n],
        phase_u: vec![f32::NAN; n],
        point_m: [vec![f32::NAN; n], vec![f32::NAN; n], vec![f32::NAN; n]],
        depth_m: vec![f32::NAN; n],
        sigma_m: vec![f32::NAN; n],
        modulation: main.modulation.data.clone(),
        background: main.background.data.clone(),
    };
    let phase_scale = (std::f64::consts::TAU / main.reference_period_px) as f32;
    let results: Vec<(PixelStatus, Option<Hit>)> = (0..n)
        .into_par_iter()
        .map(|i| pixel(&triangulator, main, columns, rows, i))
        .collect();
    for (i, (status, hit)) in results.into_iter().enumerate() {
        maps.status[i] = status;
        if let Some((p, depth, sigma)) = hit {
            for (axis, v) in maps.point_m.iter_mut().zip(p) {
                axis[i] = v;
            }
            maps.depth_m[i] = depth;
            maps.sigma_m[i] = sigma;
            maps.phase_u[i] = main.coord_px.data[i] * phase_scale;
        }
        if let Some(r) = rows.filter(|_| columns.is_some()) {
            maps.modulation[i] = maps.modulation[i].min(r.modulation.data[i]);
        }
    }
    let c = head.camera.centre_m();
    let view = [c.x as f32, c.y as f32, c.z as f32];
    Ok(Reconstruction::from_pixel_maps(
        maps,
        view,
        normals,
        Simd::best(),
    ))
}

/// A triangulated pixel: point (metres), depth, sigma along the ray.
type Hit = ([f32; 3], f32, f32);

/// One pixel: its status and, when valid, its hit.
fn pixel(
    t: &Triangulator,
    main: &AxisCoordinates,
    columns: Option<&AxisCoordinates>,
    rows: Option<&AxisCoordinates>,
    i: usize,
) -> (PixelStatus, Option<Hit>) {
    let worst = [columns, rows]
        .into_iter()
        .flatten()
        .map(|a| a.status.data[i])
        .max_by_key(|s| *s as u8)
        .unwrap_or(PixelStatus::Masked);
    if worst != PixelStatus::Valid {
        return (worst, None);
    }
    let hit = match (columns, rows) {
        (Some(c), Some(r)) => {
            let (u, v) = (c.coord_px.data[i], r.coord_px.data[i]);
            t.intersect_two_rays(i, f64::from(u), f64::from(v))
                .map(|(hit, _gap)| {
                    // The column's range sensitivity bounds the two-ray point's.
                    let sigma = t.range_per_px(i, ProjectorAxis::Column, u) * c.sigma_px.data[i];
                    (hit, sigma)
                })
        }
        _ => {
            let coord = main.coord_px.data[i];
            t.intersect(i, main.axis, coord).map(|hit| {
                let sigma = t.range_per_px(i, main.axis, coord) * main.sigma_px.data[i];
                (hit, sigma)
            })
        }
    };
    match hit {
        Some((h, sigma)) => (
            PixelStatus::Valid,
            Some(([h.point_m.x, h.point_m.y, h.point_m.z], h.depth_m, sigma)),
        ),
        None => (PixelStatus::Unreliable, None),
    }
}

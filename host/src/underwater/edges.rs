//! Pixels within the forward-scatter blur of a silhouette. Water's
//! forward scatter spreads each point's light over a Gaussian of sigma
//! `s` pixels, so a pixel near a silhouette records its own fringe plus
//! some of the other side's, whose phase belongs to another depth. No
//! restoration separates the two: the Wiener inverse cannot bring back the
//! frequencies the blur took (and its ringing at the step is itself a
//! fringe-dependent error), and a network sees the same mixture. On the
//! twin's `spheres` at T3 the band within ~2 sigma of the limb is measured
//! 70-190 um inside the sphere after classical restoration where the rest
//! is within 15 um, and it drags the fitted radii 0.1 mm small (README).
//! Such pixels are marked unreliable rather than reported.
//!
//! The margin is [`EDGE_MARGIN_SIGMAS`] sigmas: beyond 2 sigma a 1-D
//! Gaussian holds 2.3 % of its weight, so the other side's light there is
//! a few percent of the pixel's own at most.
//!
//! A silhouette is where the decoded surface ends: the border of a region
//! of undecoded pixels at least as large as the blur's disc (a smaller hole
//! is noise on a surface that continues through it), or a depth step
//! between neighbouring decoded pixels of more than [`JUMP_FRACTION`] of
//! their depth.

use crate::raster::neighbours4;
use crate::reconstruct::PixelMaps;
use crate::unwrap::PixelStatus;

/// Margin kept from a silhouette, in forward-scatter PSF sigmas.
pub const EDGE_MARGIN_SIGMAS: f64 = 2.0;

/// A depth step between 4-neighbours larger than this fraction of the
/// depth is a silhouette (5 mm at 0.5 m; a surface seen at 75 degrees
/// steps by ~2 mm per pixel of the 640x480 twin camera there).
pub const JUMP_FRACTION: f32 = 0.01;

/// The margin in whole pixels for a PSF of `psf_sigma_px` and a margin of
/// `sigmas` (0 when either is 0).
pub fn margin_px(psf_sigma_px: f64, sigmas: f64) -> usize {
    let m = psf_sigma_px * sigmas;
    if m.is_finite() && m > 0.0 {
        m.ceil() as usize
    } else {
        0
    }
}

/// Marks every valid pixel of `maps` within `radius_px` (Euclidean) of a
/// silhouette unreliable (its point, phase, depth and sigma NaN); returns
/// how many it marked. `radius_px` = 0 marks nothing.
pub fn mark_blur_edges(maps: &mut PixelMaps, radius_px: usize) -> usize {
    if radius_px == 0 {
        return 0;
    }
    let seeds = silhouette_pixels(maps, radius_px);
    let (w, h) = (maps.width as isize, maps.height as isize);
    let r = radius_px as isize;
    let disc: Vec<(isize, isize)> = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| dx * dx + dy * dy <= r * r)
        .collect();
    let mut marked = 0;
    for &i in &seeds {
        let (x, y) = ((i % maps.width) as isize, (i / maps.width) as isize);
        for &(dx, dy) in &disc {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w || ny >= h {
                continue;
            }
            let j = (ny * w + nx) as usize;
            if maps.status[j] == PixelStatus::Valid {
                maps.mark_unreliable(j);
                marked += 1;
            }
        }
    }
    marked
}

/// The pixels a silhouette passes through: undecoded pixels next to a
/// decoded one, in undecoded regions of at least the disc of `radius_px`,
/// and both pixels of a depth step.
fn silhouette_pixels(maps: &PixelMaps, radius_px: usize) -> Vec<usize> {
    let (w, h) = (maps.width, maps.height);
    let valid = |i: usize| maps.status[i] == PixelStatus::Valid;
    let large = large_undecoded_regions(maps, radius_px);
    let mut seeds = Vec::new();
    for (i, &in_large) in large.iter().enumerate() {
        let neighbours = neighbours4(i, w, h);
        let on_edge = if valid(i) {
            let d = maps.depth_m[i];
            neighbours
                .into_iter()
                .flatten()
                .any(|j| valid(j) && (maps.depth_m[j] - d).abs() > JUMP_FRACTION * d.abs())
        } else {
            in_large && neighbours.into_iter().flatten().any(valid)
        };
        if on_edge {
            seeds.push(i);
        }
    }
    seeds
}

/// Per pixel: whether it lies in a 4-connected region of undecoded pixels
/// holding at least the disc of `radius_px` (pi r^2 pixels).
fn large_undecoded_regions(maps: &PixelMaps, radius_px: usize) -> Vec<bool> {
    let (w, h) = (maps.width, maps.height);
    let n = w * h;
    let min_area = (std::f64::consts::PI * (radius_px * radius_px) as f64).ceil() as usize;
    let undecoded = |i: usize| maps.status[i] != PixelStatus::Valid;
    let mut large = vec![false; n];
    let mut seen = vec![false; n];
    let mut region = Vec::new();
    let mut stack = Vec::new();
    for start in 0..n {
        if seen[start] || !undecoded(start) {
            continue;
        }
        region.clear();
        seen[start] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            region.push(i);
            for j in neighbours4(i, w, h).into_iter().flatten() {
                if !seen[j] && undecoded(j) {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        if region.len() >= min_area {
            region.iter().for_each(|&i| large[i] = true);
        }
    }
    large
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w` x `h` map of valid pixels at depth 0.5 m.
    fn flat(w: usize, h: usize) -> PixelMaps {
        let n = w * h;
        PixelMaps {
            width: w,
            height: h,
            status: vec![PixelStatus::Valid; n],
            phase_u: vec![1.0; n],
            point_m: [vec![0.0; n], vec![0.0; n], vec![0.5; n]],
            depth_m: vec![0.5; n],
            sigma_m: vec![1e-4; n],
            modulation: vec![0.2; n],
            background: vec![0.2; n],
        }
    }

    fn valid_row(maps: &PixelMaps, y: usize) -> Vec<bool> {
        (0..maps.width)
            .map(|x| maps.status[y * maps.width + x] == PixelStatus::Valid)
            .collect()
    }

    #[test]
    fn a_margin_is_kept_from_a_large_undecoded_region() {
        // Columns 10.. undecoded (a dark background beside the surface).
        let mut maps = flat(20, 12);
        for y in 0..12 {
            for x in 10..20 {
                maps.status[y * 20 + x] = PixelStatus::Masked;
            }
        }
        let marked = mark_blur_edges(&mut maps, 3);
        assert_eq!(marked, 3 * 12);
        let row = valid_row(&maps, 5);
        assert!(row[..7].iter().all(|&v| v) && row[7..].iter().all(|&v| !v));
        assert!(maps.depth_m[5 * 20 + 8].is_nan() && maps.depth_m[5 * 20 + 6] == 0.5);
        assert_eq!(maps.status[5 * 20 + 8], PixelStatus::Unreliable);
    }

    #[test]
    fn a_small_hole_is_noise_not_a_silhouette() {
        let mut maps = flat(20, 20);
        maps.status[10 * 20 + 10] = PixelStatus::Unreliable;
        assert_eq!(mark_blur_edges(&mut maps, 3), 0);
        assert_eq!(maps.status[10 * 20 + 9], PixelStatus::Valid);
    }

    #[test]
    fn a_depth_step_marks_both_sides() {
        // Columns 10.. are 0.1 m farther: a limb before a wall.
        let mut maps = flat(20, 6);
        for y in 0..6 {
            for x in 10..20 {
                maps.depth_m[y * 20 + x] = 0.6;
            }
        }
        // Within 2 px of column 9 or of column 10.
        assert_eq!(mark_blur_edges(&mut maps, 2), 6 * 6);
        let row = valid_row(&maps, 3);
        let expected: Vec<bool> = (0..20).map(|x| !(7..13).contains(&x)).collect();
        assert_eq!(row, expected);
    }

    #[test]
    fn a_smooth_slope_is_no_step_and_zero_margin_marks_nothing() {
        let mut maps = flat(20, 6);
        for (i, d) in maps.depth_m.iter_mut().enumerate() {
            *d = 0.5 + 0.002 * (i % 20) as f32;
        }
        assert_eq!(mark_blur_edges(&mut maps.clone(), 3), 0);
        let mut holed = maps.clone();
        holed
            .status
            .iter_mut()
            .take(60)
            .for_each(|s| *s = PixelStatus::Masked);
        assert_eq!(mark_blur_edges(&mut holed, 0), 0);
        assert_eq!(margin_px(3.29, 2.0), 7);
        assert_eq!(margin_px(0.0, 2.0), 0);
        assert_eq!(margin_px(f64::NAN, 2.0), 0);
    }
}

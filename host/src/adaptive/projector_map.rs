//! Each camera pixel's optimal level placed on the DMD: a projector pixel
//! takes the lowest level any camera pixel seeing it asks for, pixels no
//! one asks about stay at the full level, and the lowered areas are grown
//! by a few pixels so a highlight edge the mapping misses by a pixel or two
//! stays covered (seed 003's projector mask, filled with `L_opt`).

use super::mapping::is_mapped;
use crate::raster::Raster;

/// Median distance in projector pixels between the positions of
/// horizontally or vertically adjacent mapped camera pixels: how much of the
/// DMD one camera pixel covers (1 when nothing is mapped).
pub fn footprint_px(uv: &Raster<[f32; 2]>) -> f32 {
    let (w, h) = uv.size();
    let mut d = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let a = uv.data[y * w + x];
            if !is_mapped(&a) {
                continue;
            }
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                if nx < w && ny < h {
                    let b = uv.data[ny * w + nx];
                    if is_mapped(&b) {
                        d.push(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt());
                    }
                }
            }
        }
    }
    if d.is_empty() {
        return 1.0;
    }
    let k = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(k, f32::total_cmp);
    m.max(1.0)
}

/// The DMD's level map: 1 everywhere, then each mapped camera pixel with a
/// finite `levels` value writes the minimum of it over the square of side
/// `footprint` around its `(u, v)`, then a minimum filter of radius
/// `grow_px` (projector pixels), then a box blur of radius `grow_px - 1`
/// (a camera pixel integrates a few DMD pixels, and a level that steps
/// inside them bends its fringe). The blur's window stays inside the grown
/// area around each request, so no requested pixel gets more than it asked.
pub fn projector_levels(
    uv: &Raster<[f32; 2]>,
    levels: &Raster<f32>,
    dmd_px: (u32, u32),
    footprint: f32,
    grow_px: usize,
) -> Raster<f32> {
    let (w, h) = (dmd_px.0 as usize, dmd_px.1 as usize);
    let mut out = Raster::filled(w, h, 1.0f32);
    let half = 0.5 * footprint.max(1.0);
    for (q, &l) in uv.data.iter().zip(&levels.data) {
        if !(l.is_finite() && is_mapped(q)) {
            continue;
        }
        // The DMD pixels whose centres lie inside the footprint.
        let x0 = (q[0] - half).ceil().max(0.0) as usize;
        let x1 = ((q[0] + half).floor() as isize).min(w as isize - 1);
        let y0 = (q[1] - half).ceil().max(0.0) as usize;
        let y1 = ((q[1] + half).floor() as isize).min(h as isize - 1);
        for y in y0 as isize..=y1 {
            for x in x0 as isize..=x1 {
                let v = &mut out.data[y as usize * w + x as usize];
                *v = v.min(l);
            }
        }
    }
    min_filter(&mut out, grow_px);
    box_blur(&mut out, grow_px.saturating_sub(1));
    out
}

/// Separable minimum filter of radius `radius` (a (2r+1) square), edges clamped.
fn min_filter(r: &mut Raster<f32>, radius: usize) {
    separable(r, radius, |w| {
        w.iter().copied().fold(f32::INFINITY, f32::min)
    });
}

/// Separable box blur of radius `radius`, edges clamped: the level then
/// varies smoothly across the few DMD pixels a camera pixel integrates.
fn box_blur(r: &mut Raster<f32>, radius: usize) {
    separable(r, radius, |w| w.iter().sum::<f32>() / w.len() as f32);
}

/// Replaces each value by `reduce` of its window of radius `radius` along
/// the rows, then along the columns (windows clamped at the edges).
fn separable(r: &mut Raster<f32>, radius: usize, reduce: impl Fn(&[f32]) -> f32) {
    if radius == 0 {
        return;
    }
    let (w, h) = r.size();
    let mut line = Vec::new();
    let mut pass =
        |r: &mut Raster<f32>, len: usize, lines: usize, at: &dyn Fn(usize, usize) -> usize| {
            for l in 0..lines {
                line.clear();
                line.extend((0..len).map(|k| r.data[at(l, k)]));
                for k in 0..len {
                    let lo = k.saturating_sub(radius);
                    let hi = (k + radius).min(len - 1);
                    r.data[at(l, k)] = reduce(&line[lo..=hi]);
                }
            }
        };
    pass(r, w, h, &|y, x| y * w + x);
    pass(r, h, w, &|x, y| y * w + x);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adaptive::mapping::UNMAPPED;

    #[test]
    fn lowest_request_wins_and_is_grown() {
        // Two camera pixels asking for levels at nearby DMD positions, one
        // unmapped, one with no request.
        let uv =
            Raster::from_vec(4, 1, vec![[5.0, 5.0], [6.0, 5.0], UNMAPPED, [15.0, 2.0]]).unwrap();
        let levels = Raster::from_vec(4, 1, vec![0.4, 0.2, 0.1, f32::NAN]).unwrap();
        let out = projector_levels(&uv, &levels, (20, 10), 1.0, 0);
        assert_eq!(*out.at(5, 5), 0.4);
        assert_eq!(*out.at(6, 5), 0.2);
        assert_eq!(*out.at(15, 2), 1.0);
        assert_eq!(out.data.iter().filter(|&&v| v < 1.0).count(), 2);
        // Grown by one (no blur): a 3x3 square around each request.
        let grown = projector_levels(&uv, &levels, (20, 10), 1.0, 1);
        assert_eq!(*grown.at(5, 5), 0.2);
        assert_eq!(*grown.at(7, 6), 0.2);
        assert_eq!(*grown.at(4, 4), 0.4);
        assert_eq!(*grown.at(8, 5), 1.0);
        // Grown by three, blurred by two: the requests keep their levels,
        // the edges ramp up to the full level.
        let smooth = projector_levels(&uv, &levels, (20, 10), 1.0, 3);
        assert!(*smooth.at(6, 5) <= 0.2 + 1e-6 && *smooth.at(5, 5) <= 0.2 + 1e-6);
        let ramp: Vec<f32> = (6..13).map(|x| *smooth.at(x, 5)).collect();
        assert!(ramp.windows(2).all(|p| p[0] <= p[1]), "{ramp:?}");
        assert!(ramp[6] == 1.0 && ramp[3] < 1.0, "{ramp:?}");
    }

    #[test]
    fn footprint_is_the_median_neighbour_distance() {
        let uv = Raster::from_fn(10, 10, |x, y| [2.0 * x as f32, 2.0 * y as f32]);
        assert_eq!(footprint_px(&uv), 2.0);
        assert_eq!(footprint_px(&Raster::filled(3, 3, UNMAPPED)), 1.0);
    }
}

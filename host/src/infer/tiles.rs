//! Tiled inference of a fixed-size network over an image of any size:
//! overlapping tiles, only those holding a pixel that needs the network,
//! run in parallel and blended with weights that ramp down over the overlap
//! (so tile seams do not show).

use rayon::prelude::*;

/// Planes of one image, channel-major (`channels x height x width`).
#[derive(Clone, Copy, Debug)]
pub struct Planes<'a> {
    /// Values.
    pub data: &'a [f32],
    /// Channels.
    pub channels: usize,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
}

/// What tiled inference gives.
#[derive(Clone, Debug, PartialEq)]
pub struct Tiled {
    /// Output planes, `out_channels x height x width`; NaN where no tile ran.
    pub data: Vec<f32>,
    /// Tiles run (each one call of the per-tile function).
    pub tiles: usize,
}

/// Tile origins along an axis of `n` pixels: tiles of `tile` overlapping by
/// at least `overlap`, the last one flush with the end; one tile at 0 when
/// the axis is shorter than a tile (it is zero-padded).
pub fn axis_origins(n: usize, tile: usize, overlap: usize) -> Vec<usize> {
    if n <= tile {
        return vec![0];
    }
    let stride = tile.saturating_sub(overlap).max(1);
    let mut v: Vec<usize> = (0..)
        .map(|k| k * stride)
        .take_while(|&o| o + tile < n)
        .collect();
    v.push(n - tile);
    v
}

/// Blending weight at position `i` of a tile of `tile`: rising over the
/// first `overlap` pixels and falling over the last, 1 between; never 0.
fn ramp(i: usize, tile: usize, overlap: usize) -> f32 {
    let edge = (i + 1).min(tile - i) as f32;
    (edge / overlap.max(1) as f32).min(1.0)
}

/// Cuts the `tile x tile` window at (`x0`, `y0`) out of `input`, zero
/// outside the image.
fn cut(input: &Planes, x0: usize, y0: usize, tile: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; input.channels * tile * tile];
    let (w, h) = (input.width, input.height);
    for c in 0..input.channels {
        for ty in 0..tile.min(h.saturating_sub(y0)) {
            let src = c * w * h + (y0 + ty) * w + x0;
            let len = tile.min(w - x0);
            let dst = c * tile * tile + ty * tile;
            out[dst..dst + len].copy_from_slice(&input.data[src..src + len]);
        }
    }
    out
}

/// Runs `eval` (tile index and one tile of `input.channels x tile x tile`
/// in, one of `out_channels x tile x tile` out; the index seeds whatever
/// randomness a sampler needs, so a run is reproducible) over every tile that holds a pixel
/// with `needed` set, in parallel, and blends the results.
pub fn infer_tiled<E: Send>(
    input: &Planes,
    needed: &[bool],
    tile: usize,
    overlap: usize,
    out_channels: usize,
    eval: impl Fn(usize, &[f32]) -> Result<Vec<f32>, E> + Sync,
) -> Result<Tiled, E> {
    let (w, h) = (input.width, input.height);
    let origins: Vec<(usize, usize)> = axis_origins(h, tile, overlap)
        .into_iter()
        .flat_map(|y| {
            axis_origins(w, tile, overlap)
                .into_iter()
                .map(move |x| (x, y))
        })
        .filter(|&(x0, y0)| {
            (y0..(y0 + tile).min(h))
                .any(|y| needed[y * w + x0..y * w + (x0 + tile).min(w)].contains(&true))
        })
        .collect();
    let outputs: Vec<Vec<f32>> = origins
        .par_iter()
        .enumerate()
        .map(|(k, &(x0, y0))| eval(k, &cut(input, x0, y0, tile)))
        .collect::<Result<_, E>>()?;
    let plane = w * h;
    let mut acc = vec![0.0f32; out_channels * plane];
    let mut weight = vec![0.0f32; plane];
    for (&(x0, y0), out) in origins.iter().zip(&outputs) {
        for ty in 0..tile.min(h - y0) {
            let wy = ramp(ty, tile, overlap);
            for tx in 0..tile.min(w - x0) {
                let wt = wy * ramp(tx, tile, overlap);
                let p = (y0 + ty) * w + x0 + tx;
                weight[p] += wt;
                for c in 0..out_channels {
                    acc[c * plane + p] += wt * out[c * tile * tile + ty * tile + tx];
                }
            }
        }
    }
    for (i, v) in acc.iter_mut().enumerate() {
        let wt = weight[i % plane];
        *v = if wt > 0.0 { *v / wt } else { f32::NAN };
    }
    Ok(Tiled {
        data: acc,
        tiles: origins.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origins_cover_the_axis_with_the_overlap() {
        assert_eq!(axis_origins(10, 16, 4), vec![0]);
        assert_eq!(axis_origins(16, 16, 4), vec![0]);
        let o = axis_origins(100, 16, 4);
        assert_eq!(o.first(), Some(&0));
        assert_eq!(o.last(), Some(&84));
        for pair in o.windows(2) {
            assert!(pair[1] - pair[0] <= 12, "{pair:?}");
        }
    }

    /// A per-pixel function comes out unchanged through tiles and blending
    /// (any seam or misplaced tile would show), and only needed tiles run.
    #[test]
    fn a_pointwise_network_is_reproduced_exactly_at_any_size() {
        for (w, h) in [(37, 23), (64, 64), (150, 70), (5, 90)] {
            let data: Vec<f32> = (0..2 * w * h).map(|i| (i as f32 * 0.37).sin()).collect();
            let planes = Planes {
                data: &data,
                channels: 2,
                width: w,
                height: h,
            };
            let needed = vec![true; w * h];
            let tile = 16;
            // out = a * b + 1, per pixel
            let out = infer_tiled::<()>(&planes, &needed, tile, 4, 1, |_, t| {
                let n = tile * tile;
                Ok((0..n).map(|i| t[i] * t[n + i] + 1.0).collect())
            })
            .unwrap();
            for p in 0..w * h {
                let want = data[p] * data[w * h + p] + 1.0;
                assert!((out.data[p] - want).abs() < 1e-5, "{w}x{h} pixel {p}");
            }
        }
    }

    #[test]
    fn tiles_without_a_needed_pixel_are_skipped_and_left_nan() {
        let (w, h) = (64, 64);
        let data = vec![1.0f32; w * h];
        let planes = Planes {
            data: &data,
            channels: 1,
            width: w,
            height: h,
        };
        let mut needed = vec![false; w * h];
        needed[2 * w + 3] = true;
        let out = infer_tiled::<()>(&planes, &needed, 16, 4, 1, |_, t| Ok(t.to_vec())).unwrap();
        assert_eq!(out.tiles, 1);
        assert_eq!(out.data[2 * w + 3], 1.0);
        assert!(out.data[60 * w + 60].is_nan());
    }

    #[test]
    fn an_error_of_one_tile_is_the_error_of_the_whole() {
        let data = vec![0.0f32; 40 * 40];
        let planes = Planes {
            data: &data,
            channels: 1,
            width: 40,
            height: 40,
        };
        let r = infer_tiled(&planes, &vec![true; 1600], 16, 4, 1, |_, _| Err("broken"));
        assert_eq!(r.unwrap_err(), "broken");
    }
}

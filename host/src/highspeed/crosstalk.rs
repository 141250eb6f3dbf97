//! The camera's colour crosstalk, measured: three flat fields, each with one
//! LED on, give how much of each LED every channel sees.

use nalgebra::Matrix3;

use super::HighSpeedError;

/// The channel <- LED mixing matrix (row: camera channel R, G, B; column: LED)
/// from `flats[led][channel]`, each a whole image with only LED `led` on. Column
/// `l` is the median over well-lit, unclipped pixels of `channel / channel l`, so
/// its diagonal is 1 and the scene's albedo cancels (an LED's narrow band meets
/// the surface with one reflectance in every channel).
pub fn crosstalk_from_flats(
    flats: [[&[f32]; 3]; 3],
    saturation_level: f32,
) -> Result<Matrix3<f64>, HighSpeedError> {
    let mut m = Matrix3::identity();
    for (led, channels) in flats.iter().enumerate() {
        let own = channels[led];
        let peak = own
            .iter()
            .copied()
            .filter(|v| v.is_finite() && *v < saturation_level)
            .fold(0.0f32, f32::max);
        let usable: Vec<usize> = (0..own.len())
            .filter(|&i| {
                own[i] > 0.25 * peak
                    && channels
                        .iter()
                        .all(|c| c[i].is_finite() && c[i] < saturation_level)
            })
            .collect();
        if usable.len() < 16 {
            return Err(HighSpeedError::BadCrosstalk);
        }
        for ch in (0..3).filter(|&ch| ch != led) {
            let mut ratios: Vec<f32> = usable.iter().map(|&i| channels[ch][i] / own[i]).collect();
            let mid = ratios.len() / 2;
            let (_, median, _) = ratios.select_nth_unstable_by(mid, f32::total_cmp);
            m[(ch, led)] = f64::from(*median);
        }
    }
    if m.try_inverse().is_none() {
        return Err(HighSpeedError::BadCrosstalk);
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mixing_comes_back_whatever_the_albedo() {
        let truth = Matrix3::new(0.9, 0.12, 0.03, 0.1, 0.85, 0.1, 0.03, 0.15, 0.88);
        let albedo: Vec<f32> = (0..400)
            .map(|i| 0.2 + 0.7 * ((i * 37) % 100) as f32 / 100.0)
            .collect();
        let flats: Vec<Vec<Vec<f32>>> = (0..3)
            .map(|led| {
                (0..3)
                    .map(|ch| albedo.iter().map(|a| a * truth[(ch, led)] as f32).collect())
                    .collect()
            })
            .collect();
        let view = |l: usize| [&flats[l][0][..], &flats[l][1][..], &flats[l][2][..]];
        let m = crosstalk_from_flats([view(0), view(1), view(2)], 0.99).unwrap();
        for led in 0..3 {
            for ch in 0..3 {
                let want = truth[(ch, led)] / truth[(led, led)];
                assert!(
                    (m[(ch, led)] - want).abs() < 1e-5,
                    "{ch} {led}: {}",
                    m[(ch, led)]
                );
            }
        }
        let dark = vec![0.0f32; 400];
        let d = [&dark[..], &dark[..], &dark[..]];
        assert!(crosstalk_from_flats([d, d, d], 0.99).is_err());
    }
}

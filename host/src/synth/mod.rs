//! A formula-based synthetic renderer for tests and benches: NOT the digital twin.
//!
//! It traces one ray per camera pixel centre into a scene of planes and spheres, checks
//! that the hit point sees the projector (shadows, back faces), projects it into the
//! projector and evaluates the pattern *formula* at that exact projector coordinate:
//!
//! ```text
//! I = ambient + gain * cos(incidence) * pattern(u, v) + N(0, sigma_I)
//! ```
//!
//! No pixel integration, blur, gamma, quantisation or clipping: the only error source is
//! the Gaussian noise of known sigma, which is what the Cramér-Rao comparisons need. The
//! digital twin (hil-sim) replaces this for realistic renders.

pub mod calibration_head;
pub mod high_speed;
pub mod targets;

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::calibration::{CameraModel, PinholeModel, Pose, ProjectorModel};
use crate::raster::Raster;

/// A surface of the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Infinite plane through `point_m` with unit `normal`.
    Plane {
        /// A point on the plane, metres.
        point_m: Point3<f64>,
        /// Unit normal.
        normal: Vector3<f64>,
    },
    /// Sphere.
    Sphere {
        /// Centre, metres.
        centre_m: Point3<f64>,
        /// Radius, metres.
        radius_m: f64,
    },
}

impl Surface {
    /// Smallest positive ray parameter of a hit along `origin + t dir` (`dir` unit).
    pub fn hit(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<f64> {
        match *self {
            Surface::Plane { point_m, normal } => {
                let den = normal.dot(dir);
                if den.abs() < 1e-12 {
                    return None;
                }
                let t = normal.dot(&(point_m - origin)) / den;
                (t > 1e-9).then_some(t)
            }
            Surface::Sphere { centre_m, radius_m } => {
                let oc = origin - centre_m;
                let b = oc.dot(dir);
                let c = oc.norm_squared() - radius_m * radius_m;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let r = disc.sqrt();
                [-b - r, -b + r].into_iter().find(|&t| t > 1e-9)
            }
        }
    }

    /// Outward unit normal at a point of the surface.
    pub fn normal_at(&self, p: &Point3<f64>) -> Vector3<f64> {
        match *self {
            Surface::Plane { normal, .. } => normal,
            Surface::Sphere { centre_m, .. } => (p - centre_m).normalize(),
        }
    }
}

/// Where each camera pixel's ray lands.
#[derive(Clone, Debug)]
pub struct GroundTruth {
    /// Hit point per pixel (world, metres), `None` for background.
    pub point_m: Raster<Option<Point3<f64>>>,
    /// Index of the surface hit.
    pub surface: Raster<Option<usize>>,
    /// Projector coordinate `(u, v)` of the hit, when lit by the projector.
    pub projector_px: Raster<Option<(f64, f64)>>,
    /// Cosine of the projector light's incidence angle (0 where unlit).
    pub shading: Raster<f32>,
}

/// Light and noise of a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Ambient light, same everywhere.
    pub ambient: f32,
    /// Projector gain: a white projector pixel on a surface facing it gives `ambient + gain`.
    pub gain: f32,
    /// Gaussian intensity noise, standard deviation.
    pub noise_sigma: f32,
}

/// Traces every camera pixel into the scene.
pub fn trace(
    surfaces: &[Surface],
    camera: &CameraModel,
    projector: &ProjectorModel,
) -> GroundTruth {
    let (w, h) = (camera.width_px as usize, camera.height_px as usize);
    let proj_centre = projector.centre_m();
    let mut truth = GroundTruth {
        point_m: Raster::filled(w, h, None),
        surface: Raster::filled(w, h, None),
        projector_px: Raster::filled(w, h, None),
        shading: Raster::filled(w, h, 0.0),
    };
    use rayon::prelude::*;
    let per_pixel: Vec<_> = (0..w * h)
        .into_par_iter()
        .map(|i| trace_pixel(surfaces, camera, projector, &proj_centre, i % w, i / w))
        .collect();
    for (i, (p, s, px, cos)) in per_pixel.into_iter().enumerate() {
        truth.point_m.data[i] = p;
        truth.surface.data[i] = s;
        truth.projector_px.data[i] = px;
        truth.shading.data[i] = cos;
    }
    truth
}

type PixelTruth = (Option<Point3<f64>>, Option<usize>, Option<(f64, f64)>, f32);

fn trace_pixel(
    surfaces: &[Surface],
    camera: &CameraModel,
    projector: &ProjectorModel,
    proj_centre: &Point3<f64>,
    x: usize,
    y: usize,
) -> PixelTruth {
    let Some(ray) = camera.pixel_ray(x as f64, y as f64) else {
        return (None, None, None, 0.0);
    };
    let Some((t, s)) = nearest_hit(surfaces, &ray.origin_m, &ray.direction) else {
        return (None, None, None, 0.0);
    };
    let p = ray.origin_m + ray.direction * t;
    let to_proj = proj_centre - p;
    let dist = to_proj.norm();
    let l = to_proj / dist;
    let cos = surfaces[s].normal_at(&p).dot(&l);
    // Closed surfaces seen from outside: a back face to the projector is unlit.
    let shadowed = nearest_hit(surfaces, &(p + l * 1e-7), &l).is_some_and(|(t2, _)| t2 < dist);
    if cos <= 0.0 || shadowed {
        return (Some(p), Some(s), None, 0.0);
    }
    match projector.project(&p).filter(|px| projector.contains(px)) {
        Some(px) => (Some(p), Some(s), Some((px.x, px.y)), cos as f32),
        None => (Some(p), Some(s), None, 0.0),
    }
}

fn nearest_hit(surfaces: &[Surface], o: &Point3<f64>, d: &Vector3<f64>) -> Option<(f64, usize)> {
    surfaces
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.hit(o, d).map(|t| (t, i)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

/// Renders one camera frame of a projected pattern given as a formula of `(u, v)` with
/// values in [0, 1]. `seed` fixes the noise (one ChaCha stream per row, so rows render in
/// parallel and the result does not depend on the thread count).
pub fn render(
    truth: &GroundTruth,
    pattern: impl Fn(f64, f64) -> f64 + Sync,
    lighting: &Lighting,
    seed: u64,
) -> Raster<f32> {
    use rayon::prelude::*;
    let noise = Normal::new(0.0f32, lighting.noise_sigma.max(0.0)).expect("finite sigma");
    let (w, h) = truth.shading.size();
    let mut out = Raster::filled(w, h, 0.0f32);
    out.data
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(y as u64);
            for (x, v) in row.iter_mut().enumerate() {
                let i = y * w + x;
                let lit = truth.projector_px.data[i]
                    .map(|(u, v)| lighting.gain * truth.shading.data[i] * pattern(u, v) as f32)
                    .unwrap_or(0.0);
                *v = lighting.ambient + lit + noise.sample(&mut rng);
            }
        });
    out
}

/// N-step fringe frames along projector columns for each period (period-major order),
/// following the DESIGN.md convention `0.5 + 0.5 cos(2 pi u / P + 2 pi n / N)`.
pub fn render_fringe_set(
    truth: &GroundTruth,
    periods_px: &[f64],
    steps: usize,
    column: bool,
    lighting: &Lighting,
    seed: u64,
) -> Vec<Raster<f32>> {
    let mut frames = Vec::new();
    for (k, &p) in periods_px.iter().enumerate() {
        for n in 0..steps {
            let delta = std::f64::consts::TAU * n as f64 / steps as f64;
            let pattern = |u: f64, v: f64| {
                let c = if column { u } else { v };
                0.5 + 0.5 * (std::f64::consts::TAU * c / p + delta).cos()
            };
            let s = seed
                .wrapping_mul(1_000_003)
                .wrapping_add((k * 64 + n) as u64 + if column { 0 } else { 1 << 32 });
            frames.push(render(truth, pattern, lighting, s));
        }
    }
    frames
}

/// A camera at the origin looking down +z and a projector `baseline_m` to its right,
/// turned to look at the point `(0, 0, working_distance_m)`.
pub fn stereo_rig(
    camera: PinholeModel,
    mut projector: PinholeModel,
    baseline_m: f64,
    working_distance_m: f64,
) -> (CameraModel, ProjectorModel) {
    let centre = Point3::new(baseline_m, 0.0, 0.0);
    let target = Point3::new(0.0, 0.0, working_distance_m);
    let z = (target - centre).normalize();
    let x = Vector3::y().cross(&z).normalize();
    let y = z.cross(&x);
    let rotation = nalgebra::Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    projector.pose = Pose {
        rotation,
        translation_m: -(rotation * centre.coords),
    };
    (camera, projector)
}

/// The two calibration spheres of the issue: radii 25.3967 and 25.3989 mm, centres
/// 100.1166 mm apart, side by side at `distance_m`, in front of a back plane.
pub fn two_spheres(distance_m: f64, back_plane_m: f64) -> Vec<Surface> {
    let half = 0.100_116_6 / 2.0;
    vec![
        Surface::Sphere {
            centre_m: Point3::new(-half, 0.0, distance_m),
            radius_m: 0.025_396_7,
        },
        Surface::Sphere {
            centre_m: Point3::new(half, 0.0, distance_m),
            radius_m: 0.025_398_9,
        },
        Surface::Plane {
            point_m: Point3::new(0.0, 0.0, back_plane_m),
            normal: -Vector3::z(),
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_and_plane_hits() {
        let s = Surface::Sphere {
            centre_m: Point3::new(0.0, 0.0, 1.0),
            radius_m: 0.1,
        };
        let t = s.hit(&Point3::origin(), &Vector3::z()).unwrap();
        assert!((t - 0.9).abs() < 1e-12);
        let p = Surface::Plane {
            point_m: Point3::new(0.0, 0.0, 2.0),
            normal: -Vector3::z(),
        };
        assert!((p.hit(&Point3::origin(), &Vector3::z()).unwrap() - 2.0).abs() < 1e-12);
        assert!(p.hit(&Point3::origin(), &-Vector3::z()).is_none());
    }

    #[test]
    fn trace_projects_into_the_projector_and_casts_shadows() {
        let (camera, projector) = stereo_rig(
            PinholeModel::ideal(80, 60, 200.0),
            PinholeModel::ideal(228, 285, 450.0),
            0.15,
            0.5,
        );
        let truth = trace(&two_spheres(0.5, 0.6), &camera, &projector);
        let lit = truth
            .projector_px
            .data
            .iter()
            .filter(|p| p.is_some())
            .count();
        let hit = truth.point_m.data.iter().filter(|p| p.is_some()).count();
        assert!(
            lit > 0 && lit < hit,
            "lit {lit} of {hit}: spheres shadow the plane"
        );
        // The centre pixel sees the back plane between the spheres, at z = 0.6.
        let c = truth.point_m.at(40, 30).unwrap();
        assert!((c.z - 0.6).abs() < 1e-9);
    }
}

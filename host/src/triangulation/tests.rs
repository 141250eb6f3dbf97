//! The triangulator against f64 references, finite differences and its own pixel path.

use super::*;
use crate::calibration::{Distortion, PinholeModel, Pose};
use nalgebra::Rotation3;

fn rig(distorted: bool) -> (CameraModel, ProjectorModel) {
    let mut camera = PinholeModel::ideal(64, 48, 80.0);
    camera.distortion = Distortion {
        k1: -0.1,
        k2: 0.02,
        p1: 0.001,
        p2: 0.0,
        k3: 0.0,
    };
    let mut projector = PinholeModel::ideal(200, 150, 220.0);
    let centre = Vector3::new(0.15, 0.02, 0.0);
    let rotation = *Rotation3::from_euler_angles(0.02, -0.3, 0.01).matrix();
    projector.pose = Pose {
        rotation,
        translation_m: -(rotation * centre),
    };
    if distorted {
        projector.distortion = Distortion {
            k1: 0.05,
            k2: -0.01,
            p1: 0.0005,
            p2: -0.0003,
            k3: 0.0,
        };
    }
    (camera, projector)
}

#[test]
fn recovers_points_from_their_projector_coordinates() {
    for distorted in [false, true] {
        let (camera, projector) = rig(distorted);
        let tri = Triangulator::new(&camera, &projector);
        for &(x, y, depth) in &[(10usize, 10usize, 0.5f64), (32, 24, 0.6), (60, 40, 0.45)] {
            let ray = camera.pixel_ray(x as f64, y as f64).unwrap();
            let truth = ray.origin_m + ray.direction * depth;
            let px = projector.project(&truth).unwrap();
            let i = y * 64 + x;
            let a = tri
                .intersect(i, ProjectorAxis::Column, px.x as f32)
                .unwrap();
            let b = tri.intersect(i, ProjectorAxis::Row, px.y as f32).unwrap();
            let (c, gap) = tri.intersect_two_rays(i, px.x, px.y).unwrap();
            for (name, got) in [("column", a), ("row", b), ("two rays", c)] {
                let err = (got.point_m.cast::<f64>() - truth).norm();
                assert!(err < 2e-5, "{name} distorted={distorted}: {err} m");
            }
            assert!(gap < 1e-6);
            assert!((f64::from(a.range_m) - depth).abs() < 2e-5);
        }
    }
}

#[test]
fn range_derivative_matches_finite_difference() {
    let (camera, projector) = rig(false);
    let tri = Triangulator::new(&camera, &projector);
    let i = 20 * 64 + 30;
    let ray = camera.pixel_ray(30.0, 20.0).unwrap();
    let u = projector
        .project(&(ray.origin_m + ray.direction * 0.5))
        .unwrap()
        .x as f32;
    let a = tri.intersect(i, ProjectorAxis::Column, u - 0.5).unwrap();
    let b = tri.intersect(i, ProjectorAxis::Column, u + 0.5).unwrap();
    let fd = (b.range_m - a.range_m).abs();
    let an = tri.range_per_px(i, ProjectorAxis::Column, u);
    assert!((fd - an).abs() < 0.01 * an, "{fd} vs {an}");
}

#[test]
fn column_runs_match_the_pixel_path() {
    for distorted in [false, true] {
        let (camera, projector) = rig(distorted);
        let tri = Triangulator::new(&camera, &projector);
        let (w, h) = tri.size();
        let mut hits = ColumnHits::default();
        let mut checked = 0;
        for y in [0usize, 13, 47] {
            // Columns of points between 0.4 and 0.7 m, plus NaN and out-of-range ones.
            let u: Vec<f32> = (0..w)
                .map(|x| {
                    let depth = 0.4 + 0.3 * ((x * 7 + y) % 11) as f64 / 10.0;
                    let ray = camera.pixel_ray(x as f64, y as f64).unwrap();
                    let px = projector.project(&(ray.origin_m + ray.direction * depth));
                    match (x % 9, px) {
                        (4, _) => f32::NAN,
                        (5, _) => 1e9,
                        (_, Some(px)) => px.x as f32,
                        (_, None) => f32::NAN,
                    }
                })
                .collect();
            tri.intersect_columns(y * w, &u, &mut hits);
            for (x, &ux) in u.iter().enumerate() {
                let i = y * w + x;
                let want = tri.intersect(i, ProjectorAxis::Column, ux);
                let got = [hits.point_m[0][x], hits.point_m[1][x], hits.point_m[2][x]];
                let Some(want) = want else {
                    assert!(got[0].is_nan() && hits.depth_m[x].is_nan(), "{x},{y}");
                    continue;
                };
                for a in 0..3 {
                    assert!(
                        (got[a] - want.point_m[a]).abs() < 2e-6,
                        "{x},{y}: {got:?} {want:?}"
                    );
                }
                assert!((hits.depth_m[x] - want.depth_m).abs() < 2e-6);
                let r = tri.range_per_px(i, ProjectorAxis::Column, ux);
                assert!(
                    (hits.range_per_px[x] - r).abs() < 1e-5 * r,
                    "{} vs {r}",
                    hits.range_per_px[x]
                );
                checked += 1;
            }
        }
        assert!(checked > 100, "{checked}");
        assert!(h > 47);
    }
}

/// The depth along pixel `index`'s stored ray whose projector column is `u_px`, in f64:
/// Newton with a numerical derivative through [`PinholeModel::project`], from `start`,
/// run to convergence (independent of the analytic f32 chain rule under test).
fn reference_depth(tri: &Triangulator, index: usize, u_px: f64, start: f64) -> Option<f64> {
    let [x, y] = tri.normalised[index].map(f64::from);
    let m = tri.camera.pose.rotation.transpose() * Vector3::new(x, y, 1.0);
    let c = tri.camera.centre_m();
    let column = |z: f64| tri.projector.project(&(c + m * z)).map(|p| p.x - u_px);
    let mut z = start;
    for _ in 0..100 {
        let h = 1e-7 * z;
        let f = column(z)?;
        let slope = (column(z + h)? - column(z - h)?) / (2.0 * h);
        let step = f / slope;
        z -= step;
        if step.abs() < 1e-15 {
            break;
        }
    }
    (column(z)?.abs() < 1e-9).then_some(z)
}

/// A wide camera (sees the whole projector image at 0.3-1.2 m) and a projector with
/// strong distortion (k1 = 0.1: ~3 % radial at the image corners).
fn wide_rig() -> Triangulator {
    let (_, mut projector) = rig(false);
    let camera = PinholeModel::ideal(64, 48, 30.0);
    projector.distortion = Distortion {
        k1: 0.1,
        k2: -0.02,
        p1: 0.001,
        p2: -0.0005,
        k3: 0.0,
    };
    Triangulator::new(&camera, &projector)
}

/// The wide rig's camera pixel (row-major index) nearest the point `range_m` along
/// projector pixel `(u, v)`'s ray, and that point; `None` off the camera image.
fn camera_pixel_seeing(
    tri: &Triangulator,
    u: f64,
    v: f64,
    range_m: f64,
) -> Option<(usize, Point3<f64>)> {
    let ray = tri.projector.pixel_ray(u, v)?;
    let point = ray.origin_m + ray.direction * range_m;
    let pixel = tri.camera.project(&point)?;
    let (x, y) = (pixel.x.round(), pixel.y.round());
    let on_image = (0.0..64.0).contains(&x) && (0.0..48.0).contains(&y);
    on_image.then_some((y as usize * 64 + x as usize, point))
}

proptest::proptest! {
    /// Random points over the whole projector image (corners included) and depth range:
    /// the vectorised distorted row path agrees with the f64 solution within 2e-6 m.
    #[test]
    fn distorted_rows_match_an_f64_reference(
        u in 0.0f64..200.0,
        v in 0.0f64..150.0,
        range_m in 0.3f64..1.2,
    ) {
        let tri = wide_rig();
        let (camera, projector) = (tri.camera, tri.projector);
        let seen = camera_pixel_seeing(&tri, u, v, range_m);
        proptest::prop_assume!(seen.is_some());
        let (index, near) = seen.unwrap();
        // The point on this pixel's stored ray at about the same depth, and its column.
        let start = camera.pose.apply(&near).z;
        let [x, y] = tri.normalised[index].map(f64::from);
        let m = camera.pose.rotation.transpose() * Vector3::new(x, y, 1.0);
        let column = projector.project(&(camera.centre_m() + m * start)).unwrap().x as f32;
        let want_z = reference_depth(&tri, index, f64::from(column), start).unwrap();
        let want = camera.centre_m() + m * want_z;

        let mut hits = ColumnHits::default();
        tri.intersect_columns(index, &[column], &mut hits);
        let got = Vector3::new(hits.point_m[0][0], hits.point_m[1][0], hits.point_m[2][0]);
        let err = (got.cast::<f64>() - want.coords).norm();
        proptest::prop_assert!(err < 2e-6, "{u},{v} at {range_m} m: {err} m");
        proptest::prop_assert!((f64::from(hits.depth_m[0]) - want_z).abs() < 2e-6);
    }
}

proptest::proptest! {
    /// The vectorised two-ray row against the f64 per-pixel path, over the whole
    /// projector image of the strongly distorted wide rig: within 2e-6 m.
    #[test]
    fn two_ray_rows_match_the_f64_path(
        u in 0.0f64..200.0,
        v in 0.0f64..150.0,
        range_m in 0.3f64..1.2,
    ) {
        let tri = wide_rig();
        let seen = camera_pixel_seeing(&tri, u, v, range_m);
        proptest::prop_assume!(seen.is_some());
        let (index, _) = seen.unwrap();
        let (want, _) = tri.intersect_two_rays(index, u, v).unwrap();
        let mut hits = ColumnHits::default();
        tri.intersect_two_rays_row(index, &[u as f32], &[v as f32], &mut hits);
        let got = Vector3::new(hits.point_m[0][0], hits.point_m[1][0], hits.point_m[2][0]);
        let err = (got - want.point_m.coords).norm();
        proptest::prop_assert!(err < 2e-6, "{u},{v} at {range_m} m: {err} m");
        proptest::prop_assert!((hits.depth_m[0] - want.depth_m).abs() < 2e-6);
        let rpp = tri.range_per_px(index, ProjectorAxis::Column, u as f32);
        proptest::prop_assert!((hits.range_per_px[0] - rpp).abs() <= 1e-4 * rpp);
    }
}

#[test]
fn two_ray_rows_refuse_what_has_no_point() {
    let tri = Triangulator::new(&rig(true).0, &rig(true).1);
    let mut hits = ColumnHits::default();
    // NaN coordinates, and a projector pixel whose ray points away from the camera's.
    tri.intersect_two_rays_row(
        0,
        &[f32::NAN, 100.0, -5.0e4],
        &[75.0, f32::NAN, 75.0],
        &mut hits,
    );
    for i in 0..3 {
        assert!(
            hits.point_m[0][i].is_nan() && hits.depth_m[i].is_nan(),
            "{i}: {hits:?}"
        );
        assert!(hits.range_per_px[i].is_nan());
    }
}

#[test]
fn parallel_lines_have_no_closest_point() {
    let a = Vector3::new(0.0, 0.0, 0.0);
    let d = Vector3::new(0.0, 0.0, 1.0);
    assert!(closest_points(&a, &d, &Vector3::new(1.0, 0.0, 0.0), &d).is_none());
}

//! The port model and the triangulator against Snell's law, their own inverses and
//! points placed in the water.

use super::*;
use crate::calibration::{Distortion, Pose};
use nalgebra::Rotation3;

fn thick() -> FlatPort {
    FlatPort::new(0.04, [0.05, -0.03, 1.0], 0.012, 1.49, 1.34).unwrap()
}

/// A camera at the origin and a distorted projector 0.15 m to its right, turned in.
fn rig() -> (CameraModel, ProjectorModel) {
    let mut camera = PinholeModel::ideal(64, 48, 60.0);
    camera.distortion = Distortion {
        k1: -0.1,
        k2: 0.02,
        p1: 0.001,
        p2: 0.0,
        k3: 0.0,
    };
    let mut projector = PinholeModel::ideal(200, 150, 180.0);
    projector.distortion = Distortion {
        k1: 0.05,
        ..Distortion::none()
    };
    let centre = Vector3::new(0.15, 0.02, 0.0);
    let rotation = *Rotation3::from_euler_angles(0.02, -0.3, 0.01).matrix();
    projector.pose = Pose {
        rotation,
        translation_m: -(rotation * centre),
    };
    (camera, projector)
}

#[test]
fn snell_holds_at_each_face_and_glass_only_shifts_the_ray() {
    let port = thick();
    let d = Vector3::new(0.4, -0.2, 1.0).normalize();
    let ray = port.refract_out(&d).unwrap();
    let n = port.normal;
    let sin = |v: &Vector3<f64>| v.cross(&n).norm();
    assert!((sin(&d) - port.water_index * sin(&ray.direction)).abs() < 1e-14);
    // Incoming ray, normal and outgoing ray are coplanar.
    assert!(d.cross(&n).dot(&ray.direction).abs() < 1e-14);
    // A parallel plate changes where the ray leaves, not its direction.
    let thin = FlatPort {
        thickness_m: 0.0,
        ..port
    };
    let bare = thin.refract_out(&d).unwrap();
    assert!((bare.direction - ray.direction).norm() < 1e-14);
    assert!((bare.origin_m - ray.origin_m).norm() > 1e-3);
    assert!((n.dot(&ray.origin_m.coords) - port.inner_m() - 0.012).abs() < 1e-15);
}

#[test]
fn refraction_fails_only_where_light_does_not_cross() {
    let z = Vector3::z();
    assert_eq!(refract(&-z, &z, 0.7), None);
    // Glass to air beyond the critical angle (41.8 degrees for 1.5).
    let d = Vector3::new(0.8, 0.0, 0.6);
    assert_eq!(refract(&d, &z, 1.5), None);
    assert!(refract(&d, &z, 1.0 / 1.5).is_some());
    assert_eq!(thick().refract_out(&Vector3::new(1.0, 0.0, -0.1)), None);
    assert_eq!(thick().aim(&Point3::new(0.0, 0.0, 0.045)), None);
}

#[test]
fn the_twin_thin_port_bends_as_snell_says() {
    // The twin's refract_out, written out: normal +z, no glass.
    let port = FlatPort::thin(0.03, 1.33).unwrap();
    let d = Vector3::new(0.5, 0.0, 1.0).normalize();
    let ray = port.refract_out(&d).unwrap();
    assert!((d.x - 1.33 * ray.direction.x).abs() < 1e-15);
    assert!((ray.origin_m - Point3::new(0.015, 0.0, 0.03)).norm() < 1e-15);
}

proptest::proptest! {
    /// Aiming at a point on a refracted ray gives back the ray's air direction, for
    /// thick tilted ports over the whole field (up to 55 degrees off axis).
    #[test]
    fn aim_inverts_refract_out(
        x in -1.4f64..1.4,
        y in -1.4f64..1.4,
        along_m in 0.001f64..2.0,
        tilt in -0.3f64..0.3,
        thickness_m in 0.0f64..0.03,
    ) {
        let port = FlatPort::new(0.03, [tilt, 0.5 * tilt, 1.0], thickness_m, 1.52, 1.34)
            .unwrap();
        let d = Vector3::new(x, y, 1.0).normalize();
        let ray = port.refract_out(&d).unwrap();
        let got = port.aim(&ray.at(along_m)).unwrap();
        proptest::prop_assert!((got - d).norm() < 1e-12, "{got} vs {d}");
    }
}

#[test]
fn recovers_points_seen_through_thick_tilted_ports() {
    let (camera, projector) = rig();
    let camera_port = thick();
    let projector_port = FlatPort::new(0.025, [-0.08, 0.0, 1.0], 0.008, 1.52, 1.34).unwrap();
    let tri = PortTriangulator::new(&camera, &camera_port, &projector, &projector_port).unwrap();
    let mut checked = 0;
    for (x, y, s) in (0..64).step_by(7).flat_map(|x| {
        (0..48)
            .step_by(7)
            .flat_map(move |y| [0.3, 0.6, 1.0, 1.5].map(|s| (x, y, s)))
    }) {
        let index = y * 64 + x;
        let ray = tri.water_ray(index).unwrap();
        let truth = ray.at(s);
        let px = project(&projector, &projector_port, &truth).unwrap();
        if !projector.contains(&px) {
            continue;
        }
        let hit = tri.intersect(index, px.x).unwrap();
        let err = (hit.point_m - truth).norm();
        assert!(err < 1e-9, "pixel ({x}, {y}) at {s} m: {err} m");
        assert!((hit.depth_m - camera.pose.apply(&truth).z).abs() < 1e-9);
        // The camera sees the point at its own pixel through its port.
        let back = project(&camera, &camera_port, &truth).unwrap();
        assert!((back - Vector2::new(x as f64, y as f64)).norm() < 1e-8);
        checked += 1;
    }
    assert!(checked >= 40, "only {checked} points lit");
    assert_eq!(tri.intersect(0, f64::NAN), None);
    let columns = vec![f32::NAN; 64 * 48];
    assert!(tri
        .intersect_columns(&columns)
        .unwrap()
        .iter()
        .all(Option::is_none));
    assert_eq!(
        tri.intersect_columns(&columns[1..]).unwrap_err(),
        FlatPortError::Columns {
            expected: 64 * 48,
            got: 64 * 48 - 1
        }
    );
}

#[test]
fn bad_ports_are_refused_with_their_values() {
    let ok = thick();
    let with = |f: fn(&mut FlatPort)| {
        let mut p = ok;
        f(&mut p);
        p.validate().unwrap_err()
    };
    assert!(matches!(
        with(|p| p.distance_m = f64::NAN),
        FlatPortError::NotFinite { field: "distance_m", value } if value.is_nan()
    ));
    assert_eq!(with(|p| p.distance_m = 0.0), FlatPortError::Distance(0.0));
    assert_eq!(
        with(|p| p.thickness_m = -1e-3),
        FlatPortError::Thickness(-1e-3)
    );
    assert_eq!(
        with(|p| p.water_index = 0.9),
        FlatPortError::Index {
            field: "water_index",
            value: 0.9
        }
    );
    assert!(matches!(
        with(|p| p.normal = Vector3::new(0.0, 0.0, 2.0)),
        FlatPortError::NormalLength { length, .. } if length == 2.0
    ));
    assert!(matches!(
        FlatPort::new(0.03, [1.0, 0.0, 0.2], 0.0, 1.5, 1.33),
        Err(FlatPortError::NormalTilt { .. })
    ));
    assert!(matches!(
        FlatPort::new(0.03, [0.0; 3], 0.0, 1.5, 1.33),
        Err(FlatPortError::NormalLength { .. })
    ));
    // Zero thickness is the twin's thin port.
    assert!(FlatPort::thin(0.03, 1.33).is_ok());
}

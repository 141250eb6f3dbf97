//! The `rotor` scene: seed 001's rotating rotor-engine model (its model is
//! about 200 x 197 mm, a rotor inside a stator, turning at 1177 rpm) for the
//! high-speed multiplexed mode: a spinner hub and seven pitched blades
//! (190 mm across) spin inside a static casing (250 mm across its flange)
//! with three stator struts behind them, in front of a wall.

use std::f64::consts::TAU;
use std::sync::Arc;

use super::{matte, single_head, wall, with_ambient, Detail};
use crate::twin::device::Rig;
use crate::twin::error::TwinError;
use crate::twin::geometry::{Pose, Shape, V3};
use crate::twin::mesh::Mesh;
use crate::twin::scene::{Motion, Object, Scene};

/// The rotor's speed, revolutions per second: seed 001 measured its
/// rotor's period as 50.98 ms (about 1177 rpm).
pub const ROTOR_REV_PER_S: f64 = 1177.0 / 60.0;
/// Centre of the rotor (its hub's base, on the spin axis), world metres.
pub const ROTOR_CENTRE_M: [f64; 3] = [0.0, 0.0, 0.48];
/// Blade tip radius, metres (tip speed 2 pi r f: 11.7 m/s, 2.3 mm per 200 us pattern).
pub const ROTOR_TIP_RADIUS_M: f64 = 0.095;
/// Number of rotor blades.
pub const ROTOR_BLADES: usize = 7;

/// Tilt of the spin axis from the camera's optical axis, radians (about
/// world x): the rotor faces the head not quite square, as a part on a test
/// stand does.
const AXIS_TILT_RAD: f64 = 0.12;
/// Blade pitch about its own radial axis, radians.
const BLADE_PITCH_RAD: f64 = 0.45;
/// Hub (spinner) radius, metres.
const HUB_RADIUS_M: f64 = 0.03;
/// Casing inner radius, metres: 10 mm of tip clearance.
const CASING_RADIUS_M: f64 = 0.105;

/// A surface of revolution about local z: the profile's (radius, z) points,
/// in order, swept around `segments` times (a zero radius closes a pole;
/// its degenerate triangles are dropped).
fn revolved(profile: &[(f64, f64)], segments: usize) -> Result<Mesh, TwinError> {
    let mut v = Vec::with_capacity(profile.len() * segments);
    for &(r, z) in profile {
        for j in 0..segments {
            let a = TAU * j as f64 / segments as f64;
            v.push([(r * a.cos()) as f32, (r * a.sin()) as f32, z as f32]);
        }
    }
    let mut t = Vec::with_capacity(2 * (profile.len() - 1) * segments);
    for i in 0..profile.len().saturating_sub(1) {
        for j in 0..segments {
            let a = (i * segments + j) as u32;
            let b = (i * segments + (j + 1) % segments) as u32;
            let (c, d) = (a + segments as u32, b + segments as u32);
            t.push([a, c, d]);
            t.push([a, d, b]);
        }
    }
    Mesh::new(&v, &t)
}

/// The rotor scene and a single head 0.48 m from the rotor.
pub(super) fn rotor(d: &Detail) -> Result<(Scene, Rig), TwinError> {
    let centre = V3::from(ROTOR_CENTRE_M);
    // Rotor frame: origin at the hub's base, local z along the spin axis
    // (away from the camera).
    let frame = Pose::new(centre, V3::new(AXIS_TILT_RAD, 0.0, 0.0));
    let axis = frame.rotation * V3::z();
    let spin = Motion::Spin {
        centre_m: centre,
        axis,
        rate_rad_s: TAU * ROTOR_REV_PER_S,
    };
    let metal = |a: f32| matte(a, a, a * 1.03);
    // Spinner: an ogive nose 32 mm proud of the blades, then a short drum.
    let nose: Vec<(f64, f64)> = (0..=8)
        .map(|i| {
            let s = i as f64 / 8.0;
            (HUB_RADIUS_M * (s * (2.0 - s)).sqrt(), -0.032 * (1.0 - s))
        })
        .chain([(HUB_RADIUS_M, 0.012)])
        .collect();
    let mut hub = Object::new(
        "hub",
        Shape::Mesh(Arc::new(revolved(&nose, 48)?)),
        metal(0.45),
        frame,
    );
    hub.motion = spin;
    let mut objects = vec![hub];
    let half_span = 0.5 * (ROTOR_TIP_RADIUS_M - HUB_RADIUS_M + 0.004);
    for k in 0..ROTOR_BLADES {
        let angle = k as f64 * TAU / ROTOR_BLADES as f64;
        // Along local x from just inside the hub to the tip, pitched about x.
        let blade = Pose::new(
            V3::new(ROTOR_TIP_RADIUS_M - half_span, 0.0, 0.0),
            V3::new(BLADE_PITCH_RAD, 0.0, 0.0),
        );
        let mut o = Object::new(
            &format!("blade-{k}"),
            Shape::Cuboid {
                half_m: V3::new(half_span, 0.014, 0.0015),
            },
            metal(0.8),
            frame * Pose::new(V3::zeros(), V3::new(0.0, 0.0, angle)) * blade,
        );
        o.motion = spin;
        objects.push(o);
    }
    // The stator: a casing ring around the blades and three struts behind them.
    let casing = revolved(
        &[
            (CASING_RADIUS_M + 0.02, -0.022),
            (CASING_RADIUS_M, -0.022),
            (CASING_RADIUS_M, 0.035),
        ],
        96,
    )?;
    objects.push(Object::new(
        "casing",
        Shape::Mesh(Arc::new(casing)),
        metal(0.55),
        frame,
    ));
    for k in 0..3 {
        let angle = 0.3 + k as f64 * TAU / 3.0;
        let half = 0.5 * (CASING_RADIUS_M - 0.01);
        let strut = Pose::new(V3::zeros(), V3::new(0.0, 0.0, angle))
            * Pose::translation(0.01 + half, 0.0, 0.03);
        objects.push(Object::new(
            &format!("strut-{k}"),
            Shape::Cuboid {
                half_m: V3::new(half, 0.008, 0.004),
            },
            metal(0.6),
            frame * strut,
        ));
    }
    objects.push(wall(0.58, 0.5));
    Ok((with_ambient(objects), single_head(d)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::cache::CameraGeometry;

    #[test]
    fn blades_turn_at_the_seeds_rate_and_stay_in_view() {
        let detail = Detail {
            camera: (160, 120),
            projector: (200, 125),
        };
        let (scene, rig) = rotor(&detail).unwrap();
        assert!(scene.is_dynamic());
        let blade = scene.objects.iter().find(|o| o.name == "blade-0").unwrap();
        let centre = V3::from(ROTOR_CENTRE_M);
        // After one period (50.98 ms) the blade is back where it started.
        let period_s = 1.0 / ROTOR_REV_PER_S;
        assert!((period_s - 0.05098).abs() < 1e-4);
        let (p0, p1) = (blade.pose_at(0.0), blade.pose_at(period_s));
        assert!((p0.translation.vector - p1.translation.vector).norm() < 1e-9);
        // The tip moves about 2.3 mm during one 200 us pattern.
        let half_span = 0.5 * (ROTOR_TIP_RADIUS_M - HUB_RADIUS_M + 0.004);
        let tip_local = nalgebra::Point3::new(half_span, 0.0, 0.0);
        let tip = |t: f64| blade.pose_at(t) * tip_local;
        let moved = (tip(2e-4) - tip(0.0)).norm();
        assert!((moved - 2.34e-3).abs() < 0.02e-3, "{moved}");
        // Every blade tip projects into the camera, the rotor fills the view's middle.
        for o in scene.objects.iter().filter(|o| o.name.starts_with("blade")) {
            let t = o.pose * tip_local;
            let r = (t.coords - centre).norm();
            assert!((r - ROTOR_TIP_RADIUS_M).abs() < 2e-3, "{r}");
            let px = rig.cameras[0].model.project(&t.coords).unwrap();
            assert!(px[0] > 0.0 && px[0] < 160.0 && px[1] > 0.0 && px[1] < 120.0);
        }
        let g = CameraGeometry::new(&scene.at(0.0), &rig, 0).unwrap();
        let seen = |name: &str| {
            g.object
                .iter()
                .filter(|&&o| {
                    scene
                        .objects
                        .get(o as usize)
                        .is_some_and(|x| x.name.starts_with(name))
                })
                .count()
        };
        for part in ["hub", "blade", "casing", "strut", "wall"] {
            assert!(seen(part) > 50, "{part}: {} pixels", seen(part));
        }
    }
}

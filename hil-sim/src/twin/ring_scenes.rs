//! Ring rigs (issue 21): K heads, each a camera with its projector, on a
//! circle around one part, so that no two heads see the whole part but all K
//! do and neighbouring heads share a strip of it (what multi-view
//! registration needs to pin every head's pose).
//!
//! ```text
//!                 head 0 (camera at the world origin, looking along +z)
//!                    |
//!   head K-1 ---- [blade] ---- head 1      ring of radius RING_RADIUS_M in the
//!                    |                     x-z plane, centred on RING_CENTRE_M;
//!                  ...                     span of the blade along world y
//! ```
//!
//! The part is turbine-blade-like: a cambered airfoil section (NACA
//! four-digit form, 30 % to 22 % thick) that tapers and twists strongly and
//! unevenly along its span (137 degrees root to tip). The strong twist is
//! what keeps any two heads from seeing it whole: a flat blade's two faces
//! are seen whole by any two heads on opposite sides of its chord line,
//! but a chord line that turns along the span puts every pair of heads on
//! the same side of it somewhere, and there neither sees the other face;
//! there too neighbouring heads see the same face, which is the overlap
//! they register on. Taper and uneven twist matter for registration: a
//! straight extrusion slides along its span and a uniformly twisted one
//! screws along it without changing shape, either leaving ICP a free
//! direction. A dim square room (walls named `wall`, so truth leaves them
//! out of "the object") is the background every head sees behind the part.

use std::f64::consts::{PI, TAU};
use std::sync::Arc;

use super::device::{Camera, Projector, Rig};
use super::error::TwinError;
use super::geometry::{Pose, Shape, V3};
use super::medium::Medium;
use super::mesh::Mesh;
use super::scene::{Albedo, Material, Object, Scene};
use super::scenes::{camera, projector, Detail};

/// Centre of the blade, world frame, metres: 0.5 m in front of head 0's
/// camera, as in every other built-in scene, and [`HEAD_RISE_M`] below it.
pub const RING_CENTRE_M: [f64; 3] = [0.0, HEAD_RISE_M, 0.5];
/// How far the ring of heads sits above the blade's centre, metres: each
/// head looks down about 13 degrees, so it sees the top faces of the root
/// platform and the tip shroud. Their normals run along the span, the one
/// direction the blade's own faces (their normals across the span) pin
/// only weakly.
pub const HEAD_RISE_M: f64 = 0.12;
/// Distance of each head's camera from the ring's centre, metres.
pub const RING_RADIUS_M: f64 = 0.5;
/// Camera-to-projector baseline of each head along the ring's tangent,
/// metres (the single head's 0.12 m).
pub const HEAD_BASELINE_M: f64 = 0.12;
/// Span of the blade (world y), metres.
pub const BLADE_SPAN_M: f64 = 0.2;
/// Chord at the root, metres (it tapers to 70 % of this at the tip).
pub const BLADE_ROOT_CHORD_M: f64 = 0.13;
/// Rotation of the blade's mid-span chord about the span axis, radians:
/// off every head's line of sight, so no head looks straight at an edge.
pub const BLADE_STAGGER_RAD: f64 = 0.35;

/// Distance from the ring's centre to each wall of the room around it, metres.
const ROOM_HALF_M: f64 = 1.0;
/// Vertices along the section's upper (and lower) side.
const CHORD_SAMPLES: usize = 90;
/// Sections along the span.
const SPAN_SECTIONS: usize = 81;

/// The blade as raw triangles in its local frame (span along local y,
/// chord along local x, thickness along local z), metres, so tests can
/// sample its surface; the first `side_triangles` triangles are the
/// lateral surface, the rest close the root and tip.
#[derive(Clone, Debug)]
pub struct BladeSurface {
    /// Vertex positions, metres.
    pub vertices: Vec<[f32; 3]>,
    /// Vertex indices, every edge shared by two triangles in opposite
    /// directions (a closed, consistently wound surface).
    pub triangles: Vec<[u32; 3]>,
    /// How many of `triangles` (the first ones) form the lateral surface.
    pub side_triangles: usize,
}

/// Section shape at span fraction `s` in [0, 1] (root to tip): chord,
/// thickness ratio, camber ratio and twist (radians).
fn section(s: f64) -> (f64, f64, f64, f64) {
    let chord = BLADE_ROOT_CHORD_M * (1.0 - 0.3 * s);
    let thickness = 0.30 - 0.08 * s;
    let camber = 0.08 - 0.02 * s;
    // Strong, uneven twist (2.4 rad root to tip): see the module doc.
    let twist = 2.4 * s * s - 1.2;
    (chord, thickness, camber, twist)
}

/// Point of the section at span fraction `s`, chord station `x` in [0, 1]
/// (leading edge 0), upper side when `upper`: NACA four-digit thickness
/// (closed trailing edge) about a parabolic camber line peaking at 40 %
/// chord, centred on its 40 % chord point, then twisted about local y.
fn section_point(s: f64, x: f64, upper: bool) -> [f32; 3] {
    let (chord, t, m, twist) = section(s);
    let half = 5.0
        * t
        * (0.2969 * x.sqrt() - 0.1260 * x - 0.3516 * x * x + 0.2843 * x.powi(3)
            - 0.1036 * x.powi(4));
    let p = 0.4;
    let camber = if x < p {
        m / (p * p) * (2.0 * p * x - x * x)
    } else {
        m / ((1.0 - p) * (1.0 - p)) * ((1.0 - 2.0 * p) + 2.0 * p * x - x * x)
    };
    let z = camber + if upper { half } else { -half };
    let (u, w) = ((x - p) * chord, z * chord);
    let (c, sn) = (twist.cos(), twist.sin());
    let y = (s - 0.5) * BLADE_SPAN_M;
    [(c * u + sn * w) as f32, y as f32, (-sn * u + c * w) as f32]
}

/// The blade's triangles (see [`BladeSurface`]).
pub fn turbine_blade() -> BladeSurface {
    // Cosine spacing: fine at the round leading edge, coarse mid-chord.
    let stations: Vec<f64> = (0..=CHORD_SAMPLES)
        .map(|i| 0.5 * (1.0 - (PI * i as f64 / CHORD_SAMPLES as f64).cos()))
        .collect();
    // One loop per section: upper side trailing edge -> leading edge, then
    // lower side leading edge -> trailing edge, both ends shared.
    let ring = 2 * CHORD_SAMPLES;
    let mut vertices = Vec::with_capacity(ring * SPAN_SECTIONS + 2);
    for j in 0..SPAN_SECTIONS {
        let s = j as f64 / (SPAN_SECTIONS - 1) as f64;
        for i in (1..=CHORD_SAMPLES).rev() {
            vertices.push(section_point(s, stations[i], true));
        }
        for &x in &stations[..CHORD_SAMPLES] {
            vertices.push(section_point(s, x, false));
        }
    }
    let mut triangles = Vec::with_capacity(2 * ring * SPAN_SECTIONS);
    for j in 0..SPAN_SECTIONS - 1 {
        for i in 0..ring {
            let a = (j * ring + i) as u32;
            let b = (j * ring + (i + 1) % ring) as u32;
            let (c, d) = (a + ring as u32, b + ring as u32);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let side_triangles = triangles.len();
    // Caps: a fan from each end section's centroid.
    for (j, flip) in [(0, true), (SPAN_SECTIONS - 1, false)] {
        let first = j * ring;
        let mut centre = [0.0f32; 3];
        for v in &vertices[first..first + ring] {
            for a in 0..3 {
                centre[a] += v[a] / ring as f32;
            }
        }
        let c = vertices.len() as u32;
        vertices.push(centre);
        for i in 0..ring {
            let (a, b) = ((first + i) as u32, (first + (i + 1) % ring) as u32);
            triangles.push(if flip { [c, b, a] } else { [c, a, b] });
        }
    }
    BladeSurface {
        vertices,
        triangles,
        side_triangles,
    }
}

/// Pose of the blade: at the ring's centre, staggered about the span axis.
pub fn blade_pose() -> Pose {
    let c = RING_CENTRE_M;
    Pose::new(
        V3::new(c[0], c[1], c[2]),
        V3::new(0.0, BLADE_STAGGER_RAD, 0.0),
    )
}

/// Position on the ring at azimuth `phi` (0: head 0, at the world origin),
/// and the ring's unit tangent there (head 0's camera x axis at 0).
fn on_ring(phi: f64) -> (V3, V3) {
    let c = V3::from(RING_CENTRE_M);
    let out = V3::new(phi.sin(), 0.0, -phi.cos());
    // World y points down: the heads sit at y = centre - rise.
    let up = V3::new(0.0, -HEAD_RISE_M, 0.0);
    (
        c + RING_RADIUS_M * out + up,
        V3::new(phi.cos(), 0.0, phi.sin()),
    )
}

/// `heads` heads evenly spaced on the ring, all aimed at its centre: head
/// `k` is camera `k` and projector `k` (names `cam-a`, `proj-a`, ...), its
/// projector [`HEAD_BASELINE_M`] along the ring from its camera, in the
/// direction of increasing k, as the single head's projector sits to its
/// camera's right.
pub fn ring_heads(detail: &Detail, heads: usize) -> Rig {
    let target = V3::from(RING_CENTRE_M);
    let (cameras, projectors): (Vec<Camera>, Vec<Projector>) = (0..heads)
        .map(|k| {
            let letter = char::from(b'a' + (k % 26) as u8);
            let (eye, tangent) = on_ring(TAU * k as f64 / heads as f64);
            (
                camera(&format!("cam-{letter}"), detail, eye, target),
                projector(
                    &format!("proj-{letter}"),
                    detail,
                    eye + HEAD_BASELINE_M * tangent,
                    target,
                ),
            )
        })
        .unzip();
    Rig {
        cameras,
        projectors,
        medium: Medium::Air,
    }
}

/// The blade and its enclosure, seen by `heads` heads on the ring.
pub fn blade_ring(detail: &Detail, heads: usize) -> Result<(Scene, Rig), TwinError> {
    let surface = turbine_blade();
    let blade = Object::new(
        "turbine-blade",
        Shape::Mesh(Arc::new(Mesh::new(&surface.vertices, &surface.triangles)?)),
        Material::matte(Albedo::Constant([0.75, 0.74, 0.72])),
        blade_pose(),
    );
    // Four two-sided walls (a sphere seen from inside would face its
    // normals away from every projector), a square room 2 m across.
    let c = V3::from(RING_CENTRE_M);
    let walls = (0..4).map(|k| {
        let yaw = TAU * k as f64 / 4.0;
        let normal = V3::new(yaw.sin(), 0.0, yaw.cos());
        Object::new(
            "wall",
            Shape::Rect {
                half_x_m: 1.0,
                half_y_m: 1.0,
            },
            Material::matte(Albedo::Constant([0.3; 3])),
            Pose::new(c + ROOM_HALF_M * normal, V3::new(0.0, yaw, 0.0)),
        )
    });
    // A turbine blade's root platform and tip shroud: slabs across the span
    // at its two ends (the root one wider than the blade, as a platform
    // is), turned with the section there.
    let slab = |name: &str, y_m: f64, twist: f64, half_m: V3| {
        Object::new(
            name,
            Shape::Cuboid { half_m },
            Material::matte(Albedo::Constant([0.7, 0.7, 0.68])),
            blade_pose() * Pose::new(V3::new(0.0, y_m, 0.0), V3::new(0.0, twist, 0.0)),
        )
    };
    let (root, tip) = (section(0.0), section(1.0));
    let half_span = 0.5 * BLADE_SPAN_M;
    let platform = slab(
        "root-platform",
        -half_span - 0.006,
        root.3,
        V3::new(0.6 * root.0, 0.006, 0.3 * root.0),
    );
    let shroud = slab(
        "tip-shroud",
        half_span + 0.004,
        tip.3,
        V3::new(0.5 * tip.0, 0.004, 0.2 * tip.0),
    );
    let scene = Scene {
        objects: [blade, platform, shroud].into_iter().chain(walls).collect(),
        // As the other scenes: about 5 % of a projector at full drive.
        ambient_surface: [0.05; 3],
        ambient_direct: [0.01; 3],
    };
    Ok((scene, ring_heads(detail, heads)))
}

/// `ring-3`: three heads 120 degrees apart.
pub fn ring3(detail: &Detail) -> Result<(Scene, Rig), TwinError> {
    blade_ring(detail, 3)
}

/// `ring-4`: four heads 90 degrees apart.
pub fn ring4(detail: &Detail) -> Result<(Scene, Rig), TwinError> {
    blade_ring(detail, 4)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::device::Pinhole;
    use crate::twin::geometry::Ray;
    use crate::twin::scene::PosedScene;
    use nalgebra::Point3;

    /// Whether `device` sees world point `p`: it projects onto the sensor
    /// (or DMD) and the first surface along the ray to it is `p` itself
    /// (so neither another part nor the blade's own far side is in the way).
    fn sees(posed: &PosedScene, device: &Pinhole, p: &V3) -> bool {
        match device.project(p) {
            Some(px) if device.contains(px) => {}
            _ => return false,
        }
        let o = device.centre();
        let dist = (p - o).norm();
        let ray = Ray {
            origin: o,
            dir: (p - o) / dist,
        };
        // 10 um: f32 vertices put the hit a few micrometres off the point.
        posed
            .intersect(&ray, 1e-6, dist + 1e-3)
            .is_some_and(|h| (h.t_m - dist).abs() < 1e-5)
    }

    /// Centroids and areas of the blade's side triangles, world frame.
    fn side_samples() -> Vec<(V3, f64)> {
        let s = turbine_blade();
        let pose = blade_pose();
        let v = |i: u32| {
            let p = s.vertices[i as usize];
            V3::new(p[0] as f64, p[1] as f64, p[2] as f64)
        };
        s.triangles[..s.side_triangles]
            .iter()
            .map(|t| {
                let (a, b, c) = (v(t[0]), v(t[1]), v(t[2]));
                let centroid = pose.transform_point(&Point3::from((a + b + c) / 3.0));
                (centroid.coords, 0.5 * (b - a).cross(&(c - a)).norm())
            })
            .collect()
    }

    /// Per head, which side samples its camera sees AND its projector
    /// lights (what a head can measure, as the twin's truth counts it).
    fn measurable(heads: usize) -> (Vec<Vec<bool>>, Vec<f64>) {
        let (scene, rig) = blade_ring(
            &Detail {
                camera: (320, 240),
                projector: (640, 400),
            },
            heads,
        )
        .unwrap();
        let posed = scene.at(0.0);
        let samples = side_samples();
        let seen = (0..heads)
            .map(|h| {
                samples
                    .iter()
                    .map(|(p, _)| {
                        sees(&posed, &rig.cameras[h].model, p)
                            && sees(&posed, &rig.projectors[h].model, p)
                    })
                    .collect()
            })
            .collect();
        (seen, samples.iter().map(|(_, a)| *a).collect())
    }

    /// Area fraction of the blade's side measurable by any head of `set`.
    fn coverage(seen: &[Vec<bool>], area: &[f64], set: &[usize]) -> f64 {
        let total: f64 = area.iter().sum();
        let covered: f64 = (0..area.len())
            .filter(|&i| set.iter().any(|&h| seen[h][i]))
            .map(|i| area[i])
            .sum();
        covered / total
    }

    #[test]
    fn the_blade_is_a_closed_surface_whose_section_tapers_and_twists_unevenly() {
        let s = turbine_blade();
        // Closed: every edge is shared by exactly two triangles, in opposite directions.
        let mut edges = std::collections::HashMap::new();
        for t in &s.triangles {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used {n} times one way");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} unpaired");
        }
        let (root, mid, tip) = (section(0.0), section(0.5), section(1.0));
        assert!(tip.0 < root.0, "taper");
        // Twist per half span differs: no screw motion maps the blade onto itself.
        assert!(((tip.3 - mid.3) - (mid.3 - root.3)).abs() > 0.1);
    }

    #[test]
    fn every_head_sees_the_blade_and_only_all_heads_together_cover_it() {
        for heads in [3, 4] {
            let (seen, area) = measurable(heads);
            let all: Vec<usize> = (0..heads).collect();
            let fused = coverage(&seen, &area, &all);
            let single: Vec<f64> = (0..heads).map(|h| coverage(&seen, &area, &[h])).collect();
            let mut pairs = Vec::new();
            for a in 0..heads {
                for b in a + 1..heads {
                    pairs.push(((a, b), coverage(&seen, &area, &[a, b])));
                }
            }
            let neighbours: Vec<f64> = (0..heads)
                .map(|h| {
                    let next = (h + 1) % heads;
                    (0..area.len())
                        .filter(|&i| seen[h][i] && seen[next][i])
                        .map(|i| area[i])
                        .sum::<f64>()
                        / area.iter().sum::<f64>()
                })
                .collect();
            println!(
                "ring-{heads}: side coverage per head {single:.3?}, pairs {pairs:.3?}, \
                 all {fused:.3}; shared by neighbours {neighbours:.3?}"
            );
            // All heads together see the whole side but the band the root
            // platform's overhang hides from heads looking down (about 1 %).
            assert!(fused > 0.98, "ring-{heads}: all heads cover {fused}");
            // No single head and no pair comes close: each head sees about
            // half the girth, and every pair misses a band (several per cent
            // of the area, not a rounding sliver) that only another head sees.
            for &c in &single {
                assert!(c > 0.2 && c < fused - 0.2, "ring-{heads}: {single:?}");
            }
            for &(pair, c) in &pairs {
                assert!(c < fused - 0.03, "ring-{heads}: pair {pair:?} covers {c}");
            }
            // Neighbours share a strip to register on. (Counted here with
            // grazing views; with camera and projector both within 70 deg of
            // the normal, where fringes keep their contrast, ring-4's strips
            // keep 4-17 % of the side but ring-3's shrink to 0-2 %, too little to
            // register heads 0 and 1 on: see tests/ring_registration.rs.)
            for &o in &neighbours {
                assert!(o > 0.05, "ring-{heads}: neighbour overlaps {neighbours:?}");
            }
        }
    }

    #[test]
    fn heads_sit_on_the_ring_and_aim_at_the_blade() {
        let (scene, rig) = ring4(&Detail::default()).unwrap();
        assert_eq!((rig.cameras.len(), rig.projectors.len()), (4, 4));
        assert_eq!(rig.cameras[3].name, "cam-d");
        let centre = V3::from(RING_CENTRE_M);
        assert!(rig.cameras[0].model.centre().norm() < 1e-12);
        for (c, p) in rig.cameras.iter().zip(&rig.projectors) {
            let d = c.model.centre() - centre;
            assert!((d.y + HEAD_RISE_M).abs() < 1e-12);
            assert!((d.xz().norm() - RING_RADIUS_M).abs() < 1e-12);
            let baseline = (p.model.centre() - c.model.centre()).norm();
            assert!((baseline - HEAD_BASELINE_M).abs() < 1e-12);
            let px = c.model.project(&centre).unwrap();
            assert!(c.model.contains(px));
        }
        assert_eq!(scene.objects[0].name, "turbine-blade");
    }
}

//! Eight rays through the BVH in one walk. The camera rays of neighbouring
//! pixels, and their shadow rays toward one projector, visit nearly the same
//! nodes, so a walk whose box and triangle tests run in eight f32 lanes (one
//! AVX2 register) does the work of eight walks for little more than one.
//!
//! Each lane gets [`Mesh::intersect`]'s or [`Mesh::occludes`]'s answer for its
//! ray: the same f32 arithmetic per lane; a lane accepts a triangle only in a
//! leaf its own ray entered, as the one-ray walk does; and of two triangles at
//! the same distance both take the lower index, so the packet's visiting order
//! (which follows the lanes together, not each ray) cannot change the result.

use super::{cross, dot, fmax, fmin, safe_inv, sub, Aabb, Mesh, Tri, MAX_DEPTH};
use crate::twin::ray::{LocalHit, Ray};

/// Rays one packet query traces together.
pub const PACKET: usize = 8;

type Lane<T> = [T; PACKET];

/// No triangle (yet) in a lane.
const NONE: u32 = u32::MAX;

/// Up to [`PACKET`] rays in the mesh frame, one f32 lane each; unused lanes
/// carry a harmless ray and a bound of -inf, so they never hit anything.
struct Lanes {
    o: [Lane<f32>; 3],
    d: [Lane<f32>; 3],
    inv: [Lane<f32>; 3],
    t_min: Lane<f32>,
}

impl Lanes {
    fn new(rays: &[Ray], t_min: impl Fn(usize) -> f64) -> Lanes {
        let mut lanes = Lanes {
            o: [[0.0; PACKET]; 3],
            d: [[0.0; PACKET]; 3],
            inv: [[1.0; PACKET]; 3],
            t_min: [0.0; PACKET],
        };
        for (l, ray) in rays.iter().enumerate() {
            let o = [ray.origin.x, ray.origin.y, ray.origin.z];
            let d = [ray.dir.x, ray.dir.y, ray.dir.z];
            for a in 0..3 {
                lanes.o[a][l] = o[a] as f32;
                lanes.d[a][l] = d[a] as f32;
                lanes.inv[a][l] = safe_inv(d[a] as f32);
            }
            lanes.t_min[l] = t_min(l) as f32;
        }
        lanes
    }
}

/// Per-lane upper bounds: `t_max` of the given rays, -inf for unused lanes.
fn bounds(count: usize, t_max: impl Fn(usize) -> f64) -> Lane<f32> {
    std::array::from_fn(|l| {
        if l < count {
            t_max(l) as f32
        } else {
            f32::NEG_INFINITY
        }
    })
}

impl Mesh {
    /// [`Mesh::intersect`] of up to [`PACKET`] rays at once (lane `l`: `rays[l]`
    /// up to `t_max[l]`); lanes past `rays.len()` are None.
    pub fn intersect_packet(
        &self,
        rays: &[Ray],
        t_min: f64,
        t_max: &[f64],
    ) -> [Option<LocalHit>; PACKET] {
        assert!(rays.len() <= PACKET && t_max.len() == rays.len());
        let lanes = Lanes::new(rays, |_| t_min);
        let (t, k) = self.traverse_packet(&lanes, bounds(rays.len(), |l| t_max[l]), false);
        let mut hits = [None; PACKET];
        for (l, ray) in rays.iter().enumerate() {
            if k[l] != NONE {
                hits[l] = Some(self.hit(ray, t[l], k[l] as usize));
            }
        }
        hits
    }

    /// [`Mesh::occludes`] of up to [`PACKET`] rays at once (lane `l`: `rays[l]`
    /// between `t_min[l]` and `t_max[l]`); lanes past `rays.len()` are false.
    pub fn occludes_packet(&self, rays: &[Ray], t_min: &[f64], t_max: &[f64]) -> [bool; PACKET] {
        assert!(rays.len() <= PACKET && t_min.len() == rays.len() && t_max.len() == rays.len());
        let lanes = Lanes::new(rays, |l| t_min[l]);
        let (_, k) = self.traverse_packet(&lanes, bounds(rays.len(), |l| t_max[l]), true);
        k.map(|k| k != NONE)
    }

    /// [`Self::walk`], built for AVX2 where the CPU has it: the lanes are then
    /// one register, not two. Same bits either way (AVX2 brings no fused
    /// multiply-add, so every lane's arithmetic is the same).
    fn traverse_packet(&self, r: &Lanes, best: Lane<f32>, any: bool) -> (Lane<f32>, Lane<u32>) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.walk_avx2(r, best, any) };
        }
        self.walk(r, best, any)
    }

    /// [`Self::walk`] compiled with AVX2 enabled.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn walk_avx2(&self, r: &Lanes, best: Lane<f32>, any: bool) -> (Lane<f32>, Lane<u32>) {
        self.walk(r, best, any)
    }

    /// The BVH walk of [`Mesh::traverse`] for all lanes at once: a node is
    /// visited when any lane's ray enters it within that lane's bound, the
    /// nearer child (by the lanes' smallest entry) first. Returns each
    /// lane's best distance and triangle (`NONE`: no hit). With `any`, a lane
    /// stops at its first hit (its bound drops to -inf) and the walk when
    /// every lane has.
    #[inline(always)]
    fn walk(&self, r: &Lanes, mut best: Lane<f32>, any: bool) -> (Lane<f32>, Lane<u32>) {
        let mut best_k = [NONE; PACKET];
        // Far children wait by index alone, and have their box tested again when
        // popped, against the bounds as they are then: a stack of entry lanes would
        // cost more to clear on every call than the second test.
        let mut stack = [0u32; MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut ni = 0usize;
        // The root is entered without a box test, as in the one-ray walk.
        let mut entry = [0.0f32; PACKET];
        'walk: loop {
            let node = &self.nodes[ni];
            if node.count > 0 {
                // Lanes whose ray did not enter this leaf accept nothing in it.
                let bound = leaf_bounds(&entry, &best);
                for k in node.first..node.first + node.count {
                    let t = tri_lanes(&self.tris[k as usize], r, &bound);
                    take_nearer(&t, k, &mut best, &mut best_k);
                }
                if any {
                    for l in 0..PACKET {
                        if best_k[l] != NONE {
                            best[l] = f32::NEG_INFINITY;
                        }
                    }
                    if best.iter().all(|&b| b == f32::NEG_INFINITY) {
                        break;
                    }
                }
            } else {
                let (a, b) = (node.first as usize, node.first as usize + 1);
                let ta = slab_lanes(&self.nodes[a].bounds, r, &best);
                let tb = slab_lanes(&self.nodes[b].bounds, r, &best);
                let (na, nb) = (nearest(&ta), nearest(&tb));
                let (near, t_near, far, n_far) = if na <= nb {
                    (a, ta, b, nb)
                } else {
                    (b, tb, a, na)
                };
                if na.min(nb).is_finite() {
                    if n_far.is_finite() {
                        stack[sp] = far as u32;
                        sp += 1;
                    }
                    ni = near;
                    entry = t_near;
                    continue;
                }
            }
            while sp > 0 {
                sp -= 1;
                let next = stack[sp] as usize;
                let t_entry = slab_lanes(&self.nodes[next].bounds, r, &best);
                if nearest(&t_entry).is_finite() {
                    ni = next;
                    entry = t_entry;
                    continue 'walk;
                }
            }
            break;
        }
        (best, best_k)
    }
}

/// Entry distance of each lane's ray into a box, +inf where it misses or
/// enters beyond the lane's bound ([`super::slab`] per lane).
#[inline(always)]
fn slab_lanes(b: &Aabb, r: &Lanes, bound: &Lane<f32>) -> Lane<f32> {
    let mut t0 = [0.0f32; PACKET];
    let mut t1 = *bound;
    for a in 0..3 {
        for l in 0..PACKET {
            let ta = (b.min[a] - r.o[a][l]) * r.inv[a][l];
            let tb = (b.max[a] - r.o[a][l]) * r.inv[a][l];
            t0[l] = fmax(t0[l], fmin(ta, tb));
            t1[l] = fmin(t1[l], fmax(ta, tb));
        }
    }
    std::array::from_fn(|l| if t0[l] <= t1[l] { t0[l] } else { f32::INFINITY })
}

/// Smallest lane entry (+inf: no lane enters), as a tree of pairs: three
/// dependent steps, not eight.
#[inline(always)]
fn nearest(t: &Lane<f32>) -> f32 {
    let four = [
        fmin(t[0], t[4]),
        fmin(t[1], t[5]),
        fmin(t[2], t[6]),
        fmin(t[3], t[7]),
    ];
    fmin(fmin(four[0], four[2]), fmin(four[1], four[3]))
}

/// Each lane's bound inside a leaf: its best so far where its ray entered
/// the leaf within it, else -inf (the lane accepts nothing there).
#[inline(always)]
fn leaf_bounds(entry: &Lane<f32>, best: &Lane<f32>) -> Lane<f32> {
    std::array::from_fn(|l| {
        if entry[l] < f32::INFINITY && entry[l] <= best[l] {
            best[l]
        } else {
            f32::NEG_INFINITY
        }
    })
}

/// [`super::tri_hit`] in every lane: the hit distance with
/// `t_min < t <= bound`, NaN where there is none.
#[inline(always)]
fn tri_lanes(t: &Tri, r: &Lanes, bound: &Lane<f32>) -> Lane<f32> {
    let mut out = [0.0f32; PACKET];
    for l in 0..PACKET {
        let o = [r.o[0][l], r.o[1][l], r.o[2][l]];
        let d = [r.d[0][l], r.d[1][l], r.d[2][l]];
        let p = cross(d, t.e2);
        let det = dot(t.e1, p);
        let inv = 1.0 / det;
        let s = sub(o, t.v0);
        let u = dot(s, p) * inv;
        let q = cross(s, t.e1);
        let v = dot(d, q) * inv;
        let tt = dot(t.e2, q) * inv;
        // The one-ray test's rejections, negated term by term: NaNs fall the same way.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let hit = !(det.abs() < 1e-20)
            & (0.0..=1.0).contains(&u)
            & !((v < 0.0) | (u + v > 1.0))
            & (tt > r.t_min[l])
            & (tt <= bound[l]);
        out[l] = if hit { tt } else { f32::NAN };
    }
    out
}

/// Takes triangle `k`'s hits `t` (NaN: none) where nearer than each lane's
/// best, or as near with a lower index than a hit already found.
#[inline(always)]
fn take_nearer(t: &Lane<f32>, k: u32, best: &mut Lane<f32>, best_k: &mut Lane<u32>) {
    let take: Lane<bool> = std::array::from_fn(|l| {
        (t[l] < best[l]) | ((t[l] == best[l]) & (best_k[l] != NONE) & (k < best_k[l]))
    });
    // Whole new lanes, not updates in place: those can become masked stores,
    // slow on AMD (seen in the host's high-speed decoder).
    *best = std::array::from_fn(|l| if take[l] { t[l] } else { best[l] });
    *best_k = std::array::from_fn(|l| if take[l] { k } else { best_k[l] });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::ray::V3;
    use proptest::prelude::*;

    /// `count` rays from around `(ox, oy, 3)` toward a small patch near
    /// `(tx, ty, 0)`: as coherent as neighbouring camera pixels.
    fn rays(count: usize, ox: f64, oy: f64, tx: f64, ty: f64, spread: f64) -> Vec<Ray> {
        (0..count)
            .map(|l| {
                let f = l as f64 - 3.5;
                let origin = V3::new(ox + 0.01 * f, oy, 3.0);
                let target = V3::new(tx + spread * f, ty - 0.5 * spread * f, 0.0);
                Ray {
                    origin,
                    dir: (target - origin).normalize(),
                }
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
        /// Random triangle soups: every lane of a packet gets the one-ray
        /// walk's nearest hit (distance and normal, to the bit) and any-hit
        /// answer, whatever the other lanes do, for full and partial packets.
        #[test]
        fn packet_lanes_equal_one_ray_walks(
            verts in proptest::collection::vec(proptest::array::uniform3(-1.0f32..1.0), 3..150),
            ox in -2.0f64..2.0, oy in -2.0f64..2.0, tx in -1.0f64..1.0, ty in -1.0f64..1.0,
            spread in 0.0f64..0.3, count in 1usize..=PACKET, t_far in 1.0f64..6.0,
        ) {
            let n = verts.len() / 3;
            let tris: Vec<[u32; 3]> = (0..n as u32).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
            let Ok(mesh) = Mesh::new(&verts, &tris) else { return Ok(()) };
            let rays = rays(count, ox, oy, tx, ty, spread);
            // Bounds differ per lane (one unbounded) so lanes prune differently.
            let t_max: Vec<f64> = (0..count)
                .map(|l| if l == 0 { f64::INFINITY } else { t_far + 0.3 * l as f64 })
                .collect();
            let t_min: Vec<f64> = (0..count).map(|l| 0.05 * l as f64).collect();
            let nearest = mesh.intersect_packet(&rays, 0.0, &t_max);
            let blocked = mesh.occludes_packet(&rays, &t_min, &t_max);
            for l in 0..PACKET {
                if l >= count {
                    prop_assert!(nearest[l].is_none() && !blocked[l]);
                    continue;
                }
                let one = mesh.intersect(&rays[l], 0.0, t_max[l]);
                let bits = |h: Option<LocalHit>| h.map(|h| (h.t_m.to_bits(), h.normal.map(f64::to_bits)));
                prop_assert_eq!(bits(nearest[l]), bits(one), "lane {}", l);
                prop_assert_eq!(blocked[l], mesh.occludes(&rays[l], t_min[l], t_max[l]), "lane {}", l);
            }
        }
    }

    /// A closed bumpy sphere seen by a fan of rays: most lanes hit, some
    /// graze or miss, and the packet agrees with one walk per ray.
    #[test]
    fn packet_agrees_on_a_closed_mesh() {
        let m = Mesh::bumpy_sphere(1.0, 40, 60, |t, p| 0.1 * (4.0 * t).sin() * (6.0 * p).cos())
            .unwrap();
        let mut hits = 0;
        for y in 0..40 {
            let ty = -1.3 + 0.065 * y as f64;
            let rays = rays(PACKET, 0.0, 0.0, -0.2, ty, 0.16);
            let t_max = vec![f64::INFINITY; PACKET];
            let packet = m.intersect_packet(&rays, 0.0, &t_max);
            for (ray, got) in rays.iter().zip(packet) {
                let one = m.intersect(ray, 0.0, f64::INFINITY);
                assert_eq!(got.map(|h| h.t_m.to_bits()), one.map(|h| h.t_m.to_bits()));
                hits += usize::from(one.is_some());
            }
        }
        assert!(
            hits > 100 && hits < 40 * PACKET,
            "{hits} hits: want a mix of hits and misses"
        );
    }
}

//! Triangle meshes and their bounding volume hierarchy (binned SAH, flat
//! f32 nodes).
//!
//! We write our own BVH rather than take a crate: it is the hot loop of the
//! twin (millions of primary and shadow rays per frame set-up), we need
//! nearest-hit and any-hit queries on one flat cache-friendly layout in f32,
//! and the candidates (`bvh`, `parry3d`) bring their own nalgebra/glam
//! versions and far more than we use. It is about 250 lines and checked
//! against brute force below; `packet.rs` walks it with eight rays at once.

use super::error::TwinError;
use super::ray::{LocalHit, Ray, V3};

mod packet;
pub use packet::PACKET;

const BINS: usize = 12;
const LEAF_MAX: usize = 4;
/// Deepest inner node: traversal keeps at most one deferred child per
/// level, so its fixed stack of this size can never overflow.
const MAX_DEPTH: usize = 60;

#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: [f32; 3],
    max: [f32; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };

    fn grow(&mut self, p: [f32; 3]) {
        for a in 0..3 {
            self.min[a] = self.min[a].min(p[a]);
            self.max[a] = self.max[a].max(p[a]);
        }
    }

    fn merge(&mut self, o: &Aabb) {
        for a in 0..3 {
            self.min[a] = self.min[a].min(o.min[a]);
            self.max[a] = self.max[a].max(o.max[a]);
        }
    }

    fn area(&self) -> f32 {
        let d = [
            self.max[0] - self.min[0],
            self.max[1] - self.min[1],
            self.max[2] - self.min[2],
        ];
        if d[0] < 0.0 {
            return 0.0;
        }
        2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
    }
}

/// One BVH node: an inner node's children are `first` and `first + 1`; a
/// leaf (count > 0) holds triangles `first .. first + count`.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    first: u32,
    count: u32,
}

/// A triangle prepared for Möller–Trumbore: corner and two edges.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v0: [f32; 3],
    e1: [f32; 3],
    e2: [f32; 3],
}

/// An indexed triangle mesh (metres, local frame) with its BVH.
#[derive(Clone, Debug)]
pub struct Mesh {
    tris: Vec<Tri>,
    nodes: Vec<Node>,
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Mesh {
    /// Builds a mesh from vertices and triangle indices; degenerate
    /// (zero-area) triangles are dropped.
    pub fn new(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<Mesh, TwinError> {
        let bad = triangles
            .iter()
            .flatten()
            .find(|&&i| i as usize >= vertices.len());
        if triangles.is_empty()
            || bad.is_some()
            || vertices.iter().flatten().any(|v| !v.is_finite())
        {
            return Err(TwinError::BadMesh {
                triangles: triangles.len(),
                vertices: vertices.len(),
                bad_index: bad.copied(),
            });
        }
        let mut tris: Vec<Tri> = Vec::with_capacity(triangles.len());
        for t in triangles {
            let v0 = vertices[t[0] as usize];
            let e1 = sub(vertices[t[1] as usize], v0);
            let e2 = sub(vertices[t[2] as usize], v0);
            let n = cross(e1, e2);
            if dot(n, n) > 0.0 {
                tris.push(Tri { v0, e1, e2 });
            }
        }
        if tris.is_empty() {
            return Err(TwinError::BadMesh {
                triangles: triangles.len(),
                vertices: vertices.len(),
                bad_index: None,
            });
        }
        let mut mesh = Mesh {
            tris,
            nodes: Vec::new(),
        };
        mesh.build();
        Ok(mesh)
    }

    /// A height field z = f(x, y) over a `size_x_m` x `size_y_m` rectangle
    /// centred on the origin, sampled on `nx` x `ny` vertices (2 triangles per cell).
    pub fn height_field(
        nx: usize,
        ny: usize,
        size_x_m: f64,
        size_y_m: f64,
        height_m: impl Fn(f64, f64) -> f64,
    ) -> Result<Mesh, TwinError> {
        if nx < 2 || ny < 2 {
            return Err(TwinError::BadParameter {
                name: "height_field n",
                value: nx.min(ny) as f64,
                why: "needs >= 2 vertices per side",
            });
        }
        let mut v = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let x = (i as f64 / (nx - 1) as f64 - 0.5) * size_x_m;
                let y = (j as f64 / (ny - 1) as f64 - 0.5) * size_y_m;
                v.push([x as f32, y as f32, height_m(x, y) as f32]);
            }
        }
        let mut t = Vec::with_capacity(2 * (nx - 1) * (ny - 1));
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let b = a + 1;
                let c = a + nx as u32;
                let d = c + 1;
                t.push([a, b, d]);
                t.push([a, d, c]);
            }
        }
        Mesh::new(&v, &t)
    }

    /// A latitude/longitude sphere of `radius_m` whose radius is modulated by
    /// `bump(theta, phi)` (relative), with 2 * n_lat * n_lon triangles.
    pub fn bumpy_sphere(
        radius_m: f64,
        n_lat: usize,
        n_lon: usize,
        bump: impl Fn(f64, f64) -> f64,
    ) -> Result<Mesh, TwinError> {
        let mut v = Vec::new();
        for i in 0..=n_lat {
            let th = std::f64::consts::PI * i as f64 / n_lat as f64;
            for j in 0..n_lon {
                let ph = 2.0 * std::f64::consts::PI * j as f64 / n_lon as f64;
                let r = radius_m * (1.0 + bump(th, ph));
                v.push([
                    (r * th.sin() * ph.cos()) as f32,
                    (r * th.sin() * ph.sin()) as f32,
                    (r * th.cos()) as f32,
                ]);
            }
        }
        let mut t = Vec::new();
        for i in 0..n_lat {
            for j in 0..n_lon {
                let a = (i * n_lon + j) as u32;
                let b = (i * n_lon + (j + 1) % n_lon) as u32;
                let c = a + n_lon as u32;
                let d = b + n_lon as u32;
                t.push([a, c, d]);
                t.push([a, d, b]);
            }
        }
        Mesh::new(&v, &t)
    }

    /// Number of (non-degenerate) triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    fn tri_bounds(t: &Tri) -> Aabb {
        let mut b = Aabb::EMPTY;
        b.grow(t.v0);
        b.grow([t.v0[0] + t.e1[0], t.v0[1] + t.e1[1], t.v0[2] + t.e1[2]]);
        b.grow([t.v0[0] + t.e2[0], t.v0[1] + t.e2[1], t.v0[2] + t.e2[2]]);
        b
    }

    fn centroid(t: &Tri) -> [f32; 3] {
        let mut c = [0.0; 3];
        for (a, c) in c.iter_mut().enumerate() {
            *c = t.v0[a] + (t.e1[a] + t.e2[a]) / 3.0;
        }
        c
    }

    fn build(&mut self) {
        let n = self.tris.len();
        let bounds: Vec<Aabb> = self.tris.iter().map(Self::tri_bounds).collect();
        let cents: Vec<[f32; 3]> = self.tris.iter().map(Self::centroid).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        self.nodes = Vec::with_capacity(2 * n);
        self.nodes.push(Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: n as u32,
        });
        let mut stack = vec![(0usize, 0usize)];
        while let Some((ni, depth)) = stack.pop() {
            let (first, count) = (self.nodes[ni].first as usize, self.nodes[ni].count as usize);
            let items = &mut order[first..first + count];
            let mut nb = Aabb::EMPTY;
            let mut cb = Aabb::EMPTY;
            for &i in items.iter() {
                nb.merge(&bounds[i as usize]);
                cb.grow(cents[i as usize]);
            }
            self.nodes[ni].bounds = nb;
            if count <= LEAF_MAX || depth >= MAX_DEPTH {
                continue;
            }
            let Some((axis, split)) = best_split(items, &bounds, &cents, &cb, nb.area(), count)
            else {
                continue;
            };
            let lo = cb.min[axis];
            let scale = BINS as f32 / (cb.max[axis] - lo);
            let bin_of = |i: u32| (((cents[i as usize][axis] - lo) * scale) as usize).min(BINS - 1);
            // Partition in place: bins < split go left.
            let mut l = 0;
            for k in 0..items.len() {
                if bin_of(items[k]) < split {
                    items.swap(k, l);
                    l += 1;
                }
            }
            if l == 0 || l == count {
                continue;
            }
            let left = self.nodes.len();
            self.nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: first as u32,
                count: l as u32,
            });
            self.nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: (first + l) as u32,
                count: (count - l) as u32,
            });
            self.nodes[ni].first = left as u32;
            self.nodes[ni].count = 0;
            stack.push((left, depth + 1));
            stack.push((left + 1, depth + 1));
        }
        self.tris = order.iter().map(|&i| self.tris[i as usize]).collect();
    }

    /// Nearest hit with `t_min < t < t_max` (ray in the mesh frame).
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<LocalHit> {
        let (t, k) = self.traverse(ray, t_min, t_max, false)?;
        Some(self.hit(ray, t, k))
    }

    /// The hit of `ray` on triangle `k` at distance `t`, its normal facing the ray.
    fn hit(&self, ray: &Ray, t: f32, k: usize) -> LocalHit {
        let tri = &self.tris[k];
        let n = cross(tri.e1, tri.e2);
        let mut normal = V3::new(n[0] as f64, n[1] as f64, n[2] as f64).normalize();
        if normal.dot(&ray.dir) > 0.0 {
            normal = -normal;
        }
        LocalHit {
            t_m: t as f64,
            normal,
        }
    }

    /// Whether any triangle lies on the ray with `t_min < t < t_max`
    /// (stops at the first one: the shadow-ray query).
    pub fn occludes(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.traverse(ray, t_min, t_max, true).is_some()
    }

    /// BVH walk, nearer child first; returns (t, triangle index) of the
    /// nearest hit (of two at the same distance, the lower index, so that
    /// any visiting order gives the same answer: see `packet`), or of the
    /// first hit found when `any` is set.
    fn traverse(&self, ray: &Ray, t_min: f64, t_max: f64, any: bool) -> Option<(f32, usize)> {
        let o = [
            ray.origin.x as f32,
            ray.origin.y as f32,
            ray.origin.z as f32,
        ];
        let d = [ray.dir.x as f32, ray.dir.y as f32, ray.dir.z as f32];
        let inv = d.map(safe_inv);
        let mut best_t = t_max as f32;
        let mut best: Option<usize> = None;
        let tmin = t_min as f32;
        // Far children wait with their entry distance: once a nearer hit is
        // found they are dropped without touching their node.
        let mut stack = [(0u32, 0.0f32); MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut ni = 0usize;
        'walk: loop {
            let node = &self.nodes[ni];
            if node.count > 0 {
                for k in node.first as usize..(node.first + node.count) as usize {
                    let Some(t) = tri_hit(&self.tris[k], o, d, tmin, best_t) else {
                        continue;
                    };
                    if t < best_t || best.is_some_and(|b| k < b) {
                        best_t = t;
                        best = Some(k);
                        if any {
                            return Some((t, k));
                        }
                    }
                }
            } else {
                let (a, b) = (node.first as usize, node.first as usize + 1);
                let ta = slab(&self.nodes[a].bounds, o, inv, best_t);
                let tb = slab(&self.nodes[b].bounds, o, inv, best_t);
                // Visit the nearer child first so best_t shrinks early.
                let (near, tn, far, tf) = if ta <= tb {
                    (a, ta, b, tb)
                } else {
                    (b, tb, a, ta)
                };
                if tn.is_finite() {
                    if tf.is_finite() {
                        stack[sp] = (far as u32, tf);
                        sp += 1;
                    }
                    ni = near;
                    continue;
                }
            }
            while sp > 0 {
                sp -= 1;
                let (next, t_entry) = stack[sp];
                // `<=`: a node entered at the best distance may hold a tie of lower index.
                if t_entry <= best_t {
                    ni = next as usize;
                    continue 'walk;
                }
            }
            break;
        }
        best.map(|k| (best_t, k))
    }
}

/// Entry distance of a ray into a box, or +inf when it misses or enters
/// beyond `t_max`.
#[inline]
fn slab(b: &Aabb, o: [f32; 3], inv: [f32; 3], t_max: f32) -> f32 {
    let mut t0 = 0.0f32;
    let mut t1 = t_max;
    for a in 0..3 {
        let ta = (b.min[a] - o[a]) * inv[a];
        let tb = (b.max[a] - o[a]) * inv[a];
        t0 = fmax(t0, fmin(ta, tb));
        t1 = fmin(t1, fmax(ta, tb));
    }
    if t0 <= t1 {
        t0
    } else {
        f32::INFINITY
    }
}

/// min without f32::min's NaN handling (one `minss`); the slab inputs are
/// never NaN because `inv` has no infinities.
#[inline(always)]
fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// max counterpart of [`fmin`].
#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Möller–Trumbore: distance of the hit with `t_min < t <= t_max` (the caller
/// decides a tie at `t_max`), or None.
#[inline]
fn tri_hit(t: &Tri, o: [f32; 3], d: [f32; 3], t_min: f32, t_max: f32) -> Option<f32> {
    let p = cross(d, t.e2);
    let det = dot(t.e1, p);
    if det.abs() < 1e-20 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(o, t.v0);
    let u = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross(s, t.e1);
    let v = dot(d, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let tt = dot(t.e2, q) * inv;
    (tt > t_min && tt <= t_max).then_some(tt)
}

/// 1 / c for a ray direction component, with no zero components: 0 * inf
/// would be NaN in the slab test.
#[inline(always)]
fn safe_inv(c: f32) -> f32 {
    1.0 / if c.abs() < 1e-12 {
        1e-12f32.copysign(c)
    } else {
        c
    }
}

/// Best binned-SAH split of `items` as (axis, first right bin), or None
/// when no split beats a leaf.
fn best_split(
    items: &[u32],
    bounds: &[Aabb],
    cents: &[[f32; 3]],
    cb: &Aabb,
    parent_area: f32,
    count: usize,
) -> Option<(usize, usize)> {
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        let lo = cb.min[axis];
        let extent = cb.max[axis] - lo;
        if extent <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent;
        let mut bb = [Aabb::EMPTY; BINS];
        let mut bc = [0usize; BINS];
        for &i in items {
            let b = (((cents[i as usize][axis] - lo) * scale) as usize).min(BINS - 1);
            bb[b].merge(&bounds[i as usize]);
            bc[b] += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in (1..BINS).rev() {
            acc.merge(&bb[b]);
            n += bc[b];
            right_area[b] = acc.area();
            right_count[b] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for split in 1..BINS {
            acc.merge(&bb[split - 1]);
            n += bc[split - 1];
            if n == 0 || right_count[split] == 0 {
                continue;
            }
            let cost = acc.area() * n as f32 + right_area[split] * right_count[split] as f32;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (cost, axis, split) = best?;
    // Leaf cost = count intersections; traversal step costs about one.
    (cost / parent_area.max(1e-30) + 1.0 < count as f32).then_some((axis, split))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn brute(m: &Mesh, ray: &Ray) -> Option<f32> {
        let o = [
            ray.origin.x as f32,
            ray.origin.y as f32,
            ray.origin.z as f32,
        ];
        let d = [ray.dir.x as f32, ray.dir.y as f32, ray.dir.z as f32];
        let mut best = None;
        let mut bt = f32::INFINITY;
        for t in &m.tris {
            if let Some(h) = tri_hit(t, o, d, 0.0, bt) {
                bt = h;
                best = Some(h);
            }
        }
        best
    }

    #[test]
    fn bvh_matches_brute_force() {
        let m = Mesh::bumpy_sphere(1.0, 20, 30, |t, p| 0.2 * (3.0 * t).sin() * (5.0 * p).cos())
            .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..500 {
            let o = V3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                4.0,
            );
            let target = V3::new(
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
                0.0,
            );
            let ray = Ray {
                origin: o,
                dir: (target - o).normalize(),
            };
            let a = m.intersect(&ray, 0.0, f64::INFINITY).map(|h| h.t_m as f32);
            assert_eq!(a, brute(&m, &ray));
        }
    }

    #[test]
    fn bad_index_is_an_error() {
        let e = Mesh::new(&[[0.0; 3], [1.0, 0.0, 0.0]], &[[0, 1, 2]]).unwrap_err();
        assert!(matches!(
            e,
            TwinError::BadMesh {
                bad_index: Some(2),
                ..
            }
        ));
    }

    #[test]
    fn height_field_hit_height() {
        let m = Mesh::height_field(11, 11, 1.0, 1.0, |_, _| 0.25).unwrap();
        let ray = Ray {
            origin: V3::new(0.1, 0.2, 2.0),
            dir: V3::new(0.0, 0.0, -1.0),
        };
        let h = m.intersect(&ray, 0.0, 10.0).unwrap();
        assert!((h.t_m - 1.75).abs() < 1e-6);
        assert!((h.normal.z - 1.0).abs() < 1e-6);
    }
}

#[cfg(test)]
mod proptests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
        /// Random triangle soups: the BVH's nearest hit and any-hit answer
        /// agree with testing every triangle.
        #[test]
        fn bvh_agrees_with_brute_force_on_soups(
            verts in proptest::collection::vec(proptest::array::uniform3(-1.0f32..1.0), 3..120),
            ox in -2.0f64..2.0, oy in -2.0f64..2.0, tx in -1.0f64..1.0, ty in -1.0f64..1.0,
        ) {
            let n = verts.len() / 3;
            let tris: Vec<[u32; 3]> = (0..n as u32).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
            let Ok(mesh) = Mesh::new(&verts, &tris) else { return Ok(()) };
            let origin = V3::new(ox, oy, 3.0);
            let ray = Ray { origin, dir: (V3::new(tx, ty, 0.0) - origin).normalize() };
            let fast = mesh.intersect(&ray, 0.0, 100.0).map(|h| h.t_m as f32);
            let o = [ox as f32, oy as f32, 3.0];
            let d = [ray.dir.x as f32, ray.dir.y as f32, ray.dir.z as f32];
            let slow = mesh.tris.iter().filter_map(|t| tri_hit(t, o, d, 0.0, 100.0)).fold(None, |b: Option<f32>, t| Some(b.map_or(t, |b| b.min(t))));
            prop_assert_eq!(fast, slow);
            prop_assert_eq!(mesh.occludes(&ray, 0.0, 100.0), slow.is_some());
        }
    }
}

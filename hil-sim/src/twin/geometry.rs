//! The analytic shapes (rectangle, sphere, cuboid) in their own local
//! frame; rays live in `ray.rs`, meshes in `mesh.rs`. Every intersection
//! returns the nearest `t > t_min` so that shadow rays can start just off a
//! surface.

use std::sync::Arc;

use super::mesh::{Mesh, PACKET};
pub use super::ray::{Frame, LocalHit, Pose, Ray, V3};

/// The geometric primitives a scene object can be.
#[derive(Clone, Debug)]
pub enum Shape {
    /// Finite rectangle in the local z = 0 plane, centred on the origin, normal +z.
    Rect {
        /// Half width along local x, metres.
        half_x_m: f64,
        /// Half height along local y, metres.
        half_y_m: f64,
    },
    /// Sphere centred on the local origin.
    Sphere {
        /// Radius, metres.
        radius_m: f64,
    },
    /// Axis-aligned box centred on the local origin.
    Cuboid {
        /// Half extents along local x, y, z, metres.
        half_m: V3,
    },
    /// Triangle mesh with its own BVH (shared, so scenes clone cheaply).
    Mesh(Arc<Mesh>),
}

impl Shape {
    /// Nearest hit with `t_min < t < t_max` of a ray given in the local frame.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<LocalHit> {
        match self {
            Shape::Rect { half_x_m, half_y_m } => rect_hit(ray, *half_x_m, *half_y_m, t_min, t_max),
            Shape::Sphere { radius_m } => sphere_hit(ray, *radius_m, t_min, t_max),
            Shape::Cuboid { half_m } => cuboid_hit(ray, half_m, t_min, t_max),
            Shape::Mesh(mesh) => mesh.intersect(ray, t_min, t_max),
        }
    }

    /// Whether anything of the shape lies on the ray with `t_min < t < t_max`.
    pub fn occludes(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        match self {
            Shape::Mesh(mesh) => mesh.occludes(ray, t_min, t_max),
            _ => self.intersect(ray, t_min, t_max).is_some(),
        }
    }

    /// [`Self::intersect`] of up to [`PACKET`] rays (lane `l`: `rays[l]` up to
    /// `t_max[l]`): a mesh walks its BVH once for all of them, other shapes
    /// take the rays one by one. Lanes past `rays.len()` are None.
    pub fn intersect_packet(
        &self,
        rays: &[Ray],
        t_min: f64,
        t_max: &[f64],
    ) -> [Option<LocalHit>; PACKET] {
        match self {
            Shape::Mesh(mesh) => mesh.intersect_packet(rays, t_min, t_max),
            _ => {
                let mut hits = [None; PACKET];
                for (l, ray) in rays.iter().enumerate() {
                    hits[l] = self.intersect(ray, t_min, t_max[l]);
                }
                hits
            }
        }
    }

    /// [`Self::occludes`] of up to [`PACKET`] rays (lane `l`: `rays[l]` between
    /// `t_min[l]` and `t_max[l]`); lanes past `rays.len()` are false.
    pub fn occludes_packet(&self, rays: &[Ray], t_min: &[f64], t_max: &[f64]) -> [bool; PACKET] {
        match self {
            Shape::Mesh(mesh) => mesh.occludes_packet(rays, t_min, t_max),
            _ => {
                let mut blocked = [false; PACKET];
                for (l, ray) in rays.iter().enumerate() {
                    blocked[l] = self.occludes(ray, t_min[l], t_max[l]);
                }
                blocked
            }
        }
    }
}

fn rect_hit(ray: &Ray, hx: f64, hy: f64, t_min: f64, t_max: f64) -> Option<LocalHit> {
    if ray.dir.z.abs() < 1e-15 {
        return None;
    }
    let t = -ray.origin.z / ray.dir.z;
    if !(t > t_min && t < t_max) {
        return None;
    }
    let p = ray.at(t);
    if p.x.abs() > hx || p.y.abs() > hy {
        return None;
    }
    // Two-sided: the normal faces the incoming ray.
    let nz = if ray.dir.z < 0.0 { 1.0 } else { -1.0 };
    Some(LocalHit {
        t_m: t,
        normal: V3::new(0.0, 0.0, nz),
    })
}

/// Ray-sphere intersection in the numerically stable form (no cancellation
/// when the sphere is small and far away).
pub fn sphere_hit(ray: &Ray, radius_m: f64, t_min: f64, t_max: f64) -> Option<LocalHit> {
    let b = ray.origin.dot(&ray.dir);
    // Distance of the centre from the ray line, computed directly.
    let closest = ray.origin - ray.dir * b;
    let disc = radius_m * radius_m - closest.norm_squared();
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let c = ray.origin.norm_squared() - radius_m * radius_m;
    let q = if b > 0.0 { -b - s } else { -b + s };
    let (mut t0, mut t1) = if q != 0.0 { (q, c / q) } else { (-b, -b) };
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    let t = if t0 > t_min && t0 < t_max {
        t0
    } else if t1 > t_min && t1 < t_max {
        t1
    } else {
        return None;
    };
    Some(LocalHit {
        t_m: t,
        normal: ray.at(t) / radius_m,
    })
}

fn cuboid_hit(ray: &Ray, half: &V3, t_min: f64, t_max: f64) -> Option<LocalHit> {
    let mut t_near = f64::NEG_INFINITY;
    let mut t_far = f64::INFINITY;
    let mut near_axis = 0;
    let mut far_axis = 0;
    for axis in 0..3 {
        let o = ray.origin[axis];
        let d = ray.dir[axis];
        if d.abs() < 1e-300 {
            if o.abs() > half[axis] {
                return None;
            }
            continue;
        }
        let mut a = (-half[axis] - o) / d;
        let mut b = (half[axis] - o) / d;
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        if a > t_near {
            t_near = a;
            near_axis = axis;
        }
        if b < t_far {
            t_far = b;
            far_axis = axis;
        }
    }
    if t_near > t_far {
        return None;
    }
    let (t, axis) = if t_near > t_min && t_near < t_max {
        (t_near, near_axis)
    } else if t_far > t_min && t_far < t_max {
        (t_far, far_axis)
    } else {
        return None;
    };
    let mut normal = V3::zeros();
    normal[axis] = if ray.at(t)[axis] > 0.0 { 1.0 } else { -1.0 };
    Some(LocalHit { t_m: t, normal })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> Ray {
        Ray {
            origin: V3::from(o),
            dir: V3::from(d).normalize(),
        }
    }

    #[test]
    fn sphere_from_outside_hits_front() {
        let h = sphere_hit(&ray([0.0, 0.0, -5.0], [0.0, 0.0, 1.0]), 1.0, 0.0, 1e9).unwrap();
        assert!((h.t_m - 4.0).abs() < 1e-12);
        assert!((h.normal - V3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    }

    #[test]
    fn sphere_from_inside_hits_back() {
        let h = sphere_hit(&ray([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]), 2.0, 1e-9, 1e9).unwrap();
        assert!((h.t_m - 2.0).abs() < 1e-12);
    }

    #[test]
    fn cuboid_face_normal() {
        let s = Shape::Cuboid {
            half_m: V3::new(1.0, 2.0, 3.0),
        };
        let h = s
            .intersect(&ray([0.5, 0.5, 10.0], [0.0, 0.0, -1.0]), 0.0, 1e9)
            .unwrap();
        assert!((h.t_m - 7.0).abs() < 1e-12);
        assert_eq!(h.normal, V3::new(0.0, 0.0, 1.0));
        assert!(s
            .intersect(&ray([1.5, 0.0, 10.0], [0.0, 0.0, -1.0]), 0.0, 1e9)
            .is_none());
    }

    #[test]
    fn rect_bounds() {
        let s = Shape::Rect {
            half_x_m: 1.0,
            half_y_m: 1.0,
        };
        assert!(s
            .intersect(&ray([0.9, 0.0, 1.0], [0.0, 0.0, -1.0]), 0.0, 1e9)
            .is_some());
        assert!(s
            .intersect(&ray([1.1, 0.0, 1.0], [0.0, 0.0, -1.0]), 0.0, 1e9)
            .is_none());
    }
}

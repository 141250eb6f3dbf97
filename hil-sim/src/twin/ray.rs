//! Rays, poses and surface hits: the vocabulary every shape (analytic in
//! `geometry.rs`, triangle meshes in `mesh.rs`) and every device speaks.

use nalgebra::{Isometry3, Point3, Vector3};

/// 3-vector of metres (or a unit direction), f64.
pub type V3 = Vector3<f64>;
/// Rigid pose `world_from_local` (rotation then translation), metres.
pub type Pose = Isometry3<f64>;

/// A ray `origin + t * dir`; `dir` is unit length so `t` is metres.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Start point, metres.
    pub origin: V3,
    /// Unit direction.
    pub dir: V3,
}

impl Ray {
    /// A placeholder ray (origin, +z) for array slots not in use.
    pub const IDLE: Ray = Ray {
        origin: V3::new(0.0, 0.0, 0.0),
        dir: V3::new(0.0, 0.0, 1.0),
    };

    /// Point at distance `t_m` along the ray.
    pub fn at(&self, t_m: f64) -> V3 {
        self.origin + self.dir * t_m
    }

    /// The same ray expressed in the frame whose `world_from_local` is `pose`.
    pub fn to_local(&self, pose: &Pose) -> Ray {
        let o = pose
            .inverse_transform_point(&Point3::from(self.origin))
            .coords;
        let d = pose.inverse_transform_vector(&self.dir);
        Ray { origin: o, dir: d }
    }
}

/// A surface hit in the shape's local frame.
#[derive(Clone, Copy, Debug)]
pub struct LocalHit {
    /// Distance along the ray, metres.
    pub t_m: f64,
    /// Outward unit normal, local frame.
    pub normal: V3,
}

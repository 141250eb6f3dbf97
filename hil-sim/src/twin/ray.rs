//! Rays, poses and surface hits: the vocabulary every shape (analytic in
//! `geometry.rs`, triangle meshes in `mesh.rs`) and every device speaks.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

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

/// A [`Pose`] as its rotation matrix, stored transposed, and translation:
/// for the per-pixel transforms, where a matrix product costs less than a
/// quaternion rotation (the twin's new pose took 0.9x the time with it).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// R^T of the pose's rotation R (world -> local).
    rt: Matrix3<f64>,
    /// The pose's translation.
    t: V3,
}

impl Frame {
    /// The frame of `pose` (`world_from_local`).
    pub fn new(pose: &Pose) -> Frame {
        Frame {
            rt: pose.rotation.to_rotation_matrix().matrix().transpose(),
            t: pose.translation.vector,
        }
    }

    /// The local frame's origin in the world.
    pub fn origin(&self) -> V3 {
        self.t
    }

    /// A world point in the local frame.
    pub fn point_to_local(&self, p: &V3) -> V3 {
        self.rt * (p - self.t)
    }

    /// A world direction in the local frame.
    pub fn vector_to_local(&self, v: &V3) -> V3 {
        self.rt * v
    }

    /// A local point in the world.
    pub fn point_to_world(&self, p: &V3) -> V3 {
        self.rt.tr_mul(p) + self.t
    }

    /// A local direction in the world.
    pub fn vector_to_world(&self, v: &V3) -> V3 {
        self.rt.tr_mul(v)
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

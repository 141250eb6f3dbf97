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
    #[inline(always)]
    pub fn point_to_local(&self, p: &V3) -> V3 {
        self.vector_to_local(&(p - self.t))
    }

    /// A world direction in the local frame.
    #[inline(always)]
    pub fn vector_to_local(&self, v: &V3) -> V3 {
        let m = &self.rt;
        // Row by row, in nalgebra's order of a matrix-vector product (the
        // same bits): written out, the lanes stay in registers instead of
        // passing through stack temporaries.
        V3::new(
            m[(0, 0)] * v.x + m[(0, 1)] * v.y + m[(0, 2)] * v.z,
            m[(1, 0)] * v.x + m[(1, 1)] * v.y + m[(1, 2)] * v.z,
            m[(2, 0)] * v.x + m[(2, 1)] * v.y + m[(2, 2)] * v.z,
        )
    }

    /// A local point in the world.
    #[inline(always)]
    pub fn point_to_world(&self, p: &V3) -> V3 {
        self.vector_to_world(p) + self.t
    }

    /// A local direction in the world.
    #[inline(always)]
    pub fn vector_to_world(&self, v: &V3) -> V3 {
        let m = &self.rt;
        V3::new(
            m[(0, 0)] * v.x + m[(1, 0)] * v.y + m[(2, 0)] * v.z,
            m[(0, 1)] * v.x + m[(1, 1)] * v.y + m[(2, 1)] * v.z,
            m[(0, 2)] * v.x + m[(1, 2)] * v.y + m[(2, 2)] * v.z,
        )
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

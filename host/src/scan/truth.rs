//! A scan's ground truth as plain data, whatever gave it: per camera, the
//! true surface point and normal behind every pixel, which pixels see the
//! object lit by the head's own projector, which pixels both projectors
//! light, and the camera's true pose. The digital twin gives one
//! (`crate::sim::truth::ground_truth`); a measured reference (a CMM model
//! rendered into each calibrated camera) can give another, and
//! [`super::measure`] serves both.

use nalgebra::Isometry3;

/// The truth behind one camera's pixels (row-major, as the camera's frames).
#[derive(Clone, Debug)]
pub struct CameraTruth {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The camera's true pose: reference (world) frame -> camera frame.
    pub camera_from_world: Isometry3<f64>,
    /// Per pixel: the true surface point, world frame, metres (NaN: no surface).
    pub point_m: Vec<[f32; 3]>,
    /// Per pixel: the true unit normal, world frame (NaN: no surface).
    pub normal: Vec<[f32; 3]>,
    /// Per pixel: index of the truth's object seen there (`u16::MAX`: none);
    /// [`TrueSphere::object`] refers to it.
    pub object: Vec<u16>,
    /// Per pixel: sees the measured object (not the background) and is lit
    /// by this head's own projector: what the head should measure.
    pub own_object: Vec<bool>,
    /// Per pixel: the surface point is lit by two or more projectors.
    pub overlap: Vec<bool>,
}

/// A sphere of known size in the scene (a calibration sphere).
#[derive(Clone, Debug, PartialEq)]
pub struct TrueSphere {
    /// Its name, for the report.
    pub name: String,
    /// The object index the cameras' [`CameraTruth::object`] give it.
    pub object: u16,
    /// Centre, world frame, metres.
    pub centre_m: [f64; 3],
    /// Radius, metres.
    pub radius_m: f64,
}

/// The truth of a whole scan: one [`CameraTruth`] per head, in head order.
#[derive(Clone, Debug)]
pub struct GroundTruth {
    /// Per head, its camera's truth.
    pub cameras: Vec<CameraTruth>,
    /// Spheres of known size the scene holds (none is fine).
    pub spheres: Vec<TrueSphere>,
    /// Whether the scan reconstructs with the truth's own devices, so its
    /// calibrated frames are the true ones (else each cloud's frame is
    /// fitted onto the truth before measuring, `super::truth_frame`).
    pub calibration_is_true: bool,
}

/// A truth whose per-pixel arrays do not match its image size.
#[derive(Debug, thiserror::Error)]
#[error("ground truth of head {head}: {field} has {got} entries for a {width}x{height} image")]
pub struct TruthSizeError {
    /// Head index.
    pub head: usize,
    /// The array.
    pub field: &'static str,
    /// Its length.
    pub got: usize,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

impl CameraTruth {
    /// Per pixel: whether a true surface lies behind it.
    pub fn has_surface(&self) -> Vec<bool> {
        self.point_m.iter().map(|p| p[0].is_finite()).collect()
    }
}

impl GroundTruth {
    /// Checks that every per-pixel array has one entry per pixel.
    pub fn validate(&self) -> Result<(), TruthSizeError> {
        for (head, c) in self.cameras.iter().enumerate() {
            let lengths = [
                ("point_m", c.point_m.len()),
                ("normal", c.normal.len()),
                ("object", c.object.len()),
                ("own_object", c.own_object.len()),
                ("overlap", c.overlap.len()),
            ];
            for (field, got) in lengths {
                if got != c.width * c.height {
                    return Err(TruthSizeError {
                        head,
                        field,
                        got,
                        width: c.width,
                        height: c.height,
                    });
                }
            }
        }
        Ok(())
    }

    /// Head `h`'s true frame (its camera frame) from the world frame.
    pub fn head_from_world(&self, h: usize) -> Isometry3<f64> {
        self.cameras[h].camera_from_world
    }

    /// Head `a`'s true frame -> head `b`'s.
    pub fn b_from_a(&self, a: usize, b: usize) -> Isometry3<f64> {
        self.head_from_world(b) * self.head_from_world(a).inverse()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn camera(x_m: f64, pixels: usize) -> CameraTruth {
        CameraTruth {
            width: pixels,
            height: 1,
            camera_from_world: Isometry3::translation(x_m, 0.0, 0.0),
            point_m: vec![[0.0, 0.0, 0.5]; pixels],
            normal: vec![[0.0, 0.0, -1.0]; pixels],
            object: vec![0; pixels],
            own_object: vec![true; pixels],
            overlap: vec![false; pixels],
        }
    }

    #[test]
    fn head_to_head_pose_comes_from_the_two_camera_poses() {
        let truth = GroundTruth {
            cameras: vec![camera(0.1, 2), camera(-0.2, 2)],
            spheres: Vec::new(),
            calibration_is_true: true,
        };
        truth.validate().unwrap();
        let t = truth.b_from_a(0, 1).translation.vector;
        assert!((t - Vector3::new(-0.3, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn arrays_of_the_wrong_length_are_named() {
        let mut bad = camera(0.0, 3);
        bad.overlap.pop();
        let err = GroundTruth {
            cameras: vec![camera(0.0, 3), bad],
            spheres: Vec::new(),
            calibration_is_true: true,
        }
        .validate()
        .unwrap_err();
        assert_eq!((err.head, err.field, err.got), (1, "overlap", 2));
    }
}

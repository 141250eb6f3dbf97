//! A simulated head rendered by the digital twin (hil_sim::twin), with its truth.
//!
//! The twin's single-head rig (`scenes::single_head`) looks at the twin's 9x7-square
//! checkerboard (`scenes::CHECKERBOARD`, 8x6 inner corners of 20 mm) held at `views`
//! poses in front of a dim wall. Each view is a ray-cast render lit by the projector's
//! white field, whose pixels integrate 4x4 rays over their area (one ray per pixel
//! would alias the square edges and bias the corners by about 0.16 px), and, for the
//! projector, x and y fringes (4 steps at three periods each, one ray per pixel)
//! decoded and heterodyne-unwrapped by slscan's own phase and unwrap code into the
//! absolute phase maps `calibrate_head` expects. The truth is the twin's device set,
//! converted by [`super::from_twin`].

use std::f64::consts::TAU;
use std::sync::Arc;

use hil_sim::twin::scenes::{single_head, Detail, CHECKERBOARD};
use hil_sim::twin::{
    look_at, Albedo, BitDepth, Exposure, Fringe, Material, Object, Pattern, ProjectorTimeline,
    Renderer, Rig, Scene, SensorModel, Shape, TwinError, CALIBRATION_PIXEL_SAMPLES, V3,
};
use nalgebra::Vector3;

use super::from_twin::{head_from_twin, pose_from_twin};
use crate::calibration::board::{Checkerboard, GrayImage};
use crate::calibration::head::{BoardCapture, ProjectorSpec};
use crate::calibration::{Head, Pose};
use crate::phase::{PhaseShift, WrappedPhase};
use crate::raster::Raster;
use crate::synth::calibration_head::TILTS;
use crate::unwrap::heterodyne::Heterodyne;

/// Fringe periods of the phase maps, DMD pixels, finest first (beat 1320 px).
pub const PERIODS_PX: [f64; 3] = [20.0, 22.0, 24.0];
/// Phase steps per period.
const STEPS: usize = 4;
/// Pattern on and shutter open, seconds: white squares reach about 70 % of full well.
const EXPOSURE_S: f64 = 0.6e-3;

/// A twin head and the board poses it is shown.
#[derive(Debug, Clone)]
pub struct TwinHead {
    /// The twin's rig: camera 0 and projector 0 form the head.
    pub rig: Rig,
    /// The rig's true devices as a head (camera frame = head frame).
    pub truth: Head,
    /// Per view: the board object's pose in the twin world (`world_from_board`, board
    /// centred on its local origin as the twin draws it).
    pub world_from_board: Vec<hil_sim::twin::Pose>,
    /// Rays per camera pixel and axis the views are rendered with (each pixel
    /// integrates over its area; default [`CALIBRATION_PIXEL_SAMPLES`]).
    pub pixel_samples: u32,
}

/// The twin's checkerboard in slscan's terms (inner corners, origin at corner (0, 0)).
pub fn board() -> Checkerboard {
    Checkerboard {
        cols: (CHECKERBOARD.squares_x - 1) as usize,
        rows: (CHECKERBOARD.squares_y - 1) as usize,
        square_m: CHECKERBOARD.square_m,
    }
}

impl TwinHead {
    /// The twin's single head at `detail` and `views` board poses (at most 15) at
    /// 0.45..0.55 m in front of the camera.
    pub fn standard(views: usize, detail: &Detail) -> Self {
        let rig = single_head(detail);
        let world_from_board = TILTS
            .iter()
            .take(views.min(TILTS.len()))
            .enumerate()
            .map(|(k, &(a, b, c))| {
                let z = 0.45 + 0.05 * (k % 3) as f64;
                // Spread over the image (the 0.16 x 0.12 m board covers about a third
                // of it) so that the distortion is seen towards the corners.
                let x = 0.04 * ((k % 5) as f64 - 2.0);
                let y = 0.05 * ((k % 4) as f64 / 1.5 - 1.0);
                hil_sim::twin::Pose::new(V3::new(x, y, z), V3::new(a, b, c))
            })
            .collect();
        Self::with_rig(rig, world_from_board)
    }

    fn with_rig(rig: Rig, world_from_board: Vec<hil_sim::twin::Pose>) -> Self {
        let truth = head_from_twin(&rig, 0, 0, "truth").expect("a rig of one head");
        Self {
            rig,
            truth,
            world_from_board,
            pixel_samples: CALIBRATION_PIXEL_SAMPLES,
        }
    }

    /// A second head 15 cm to the left (its own camera intrinsics and lens, its projector
    /// 12 cm to the camera's right as in head 0), aimed at the same boards and rendered
    /// with the same pixel samples; returns it and the true head-0 camera -> head-1
    /// camera pose.
    pub fn second_head(&self) -> (TwinHead, Pose) {
        let mut rig = self.rig.clone();
        let target = V3::new(0.0, 0.0, 0.5);
        let down = V3::new(0.0, -1.0, 0.0);
        let cam = &mut rig.cameras[0];
        cam.name = "cam-b".into();
        cam.model.world_from_device = look_at(V3::new(-0.15, 0.0, 0.04), target, down);
        cam.model.intrinsics.fx *= 1.03;
        cam.model.intrinsics.fy *= 1.025;
        cam.model.intrinsics.cx -= 2.0;
        cam.model.intrinsics.cy += 1.5;
        cam.model.distortion.k1 = -0.12;
        cam.model.distortion.p1 = -0.0006;
        let proj = &mut rig.projectors[0];
        proj.name = "proj-b".into();
        proj.model.world_from_device = look_at(
            V3::new(-0.03, 0.0, 0.04),
            target + V3::new(0.0, 0.09, 0.0),
            down,
        );
        let a_world_to_cam = pose_from_twin(&self.rig.cameras[0].model.world_from_device);
        let b_world_to_cam = pose_from_twin(&rig.cameras[0].model.world_from_device);
        let a_to_b = b_world_to_cam.compose(&a_world_to_cam.inverse());
        let second = Self {
            pixel_samples: self.pixel_samples,
            ..Self::with_rig(rig, self.world_from_board.clone())
        };
        (second, a_to_b)
    }

    /// The projector spec the calibration is told.
    pub fn projector_spec(&self) -> ProjectorSpec {
        let k = &self.rig.projectors[0].model.intrinsics;
        ProjectorSpec {
            width_px: k.width,
            height_px: k.height,
            period_px: PERIODS_PX[0],
        }
    }

    /// True board -> camera pose of view `v` in slscan's board frame (origin at inner
    /// corner (0, 0)). The board is point-symmetric, so a detector may number the
    /// corners from the opposite end: see [`Self::flipped_board_pose`].
    pub fn board_pose(&self, v: usize) -> Pose {
        let b = board();
        // slscan corner (0, 0) in the twin board's local frame.
        let origin = Vector3::new(
            (1.0 - 0.5 * CHECKERBOARD.squares_x as f64) * b.square_m,
            (1.0 - 0.5 * CHECKERBOARD.squares_y as f64) * b.square_m,
            0.0,
        );
        let board_to_world = pose_from_twin(&self.world_from_board[v]).inverse();
        let board_to_world = Pose {
            rotation: board_to_world.rotation,
            translation_m: board_to_world.translation_m + board_to_world.rotation * origin,
        };
        pose_from_twin(&self.rig.cameras[0].model.world_from_device).compose(&board_to_world)
    }

    /// [`Self::board_pose`] with the corners numbered from the opposite end (the board
    /// turned 180 degrees about its normal), as a detector may number a point-symmetric
    /// board.
    pub fn flipped_board_pose(&self, v: usize) -> Pose {
        let b = board();
        let turn = Pose {
            rotation: nalgebra::Matrix3::new(-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0),
            translation_m: Vector3::new(
                (b.cols - 1) as f64 * b.square_m,
                (b.rows - 1) as f64 * b.square_m,
                0.0,
            ),
        };
        self.board_pose(v).compose(&turn)
    }

    /// The scene of view `v`: the board in front of a dim wall, with ambient light.
    fn scene(&self, v: usize) -> Scene {
        let wall = Object::new(
            "wall",
            Shape::Rect {
                half_x_m: 1.5,
                half_y_m: 1.5,
            },
            Material::matte(Albedo::Constant([0.3; 3])),
            hil_sim::twin::Pose::translation(0.0, 0.0, 0.65),
        );
        Scene {
            objects: vec![CHECKERBOARD.object(self.world_from_board[v]), wall],
            ambient_surface: [0.05; 3],
            ambient_direct: [0.01; 3],
        }
    }

    /// Renders every view with `sensor`: the board under the projector's white field and,
    /// with `with_phase`, absolute phase maps in x and y.
    pub fn render(
        &self,
        sensor: &SensorModel,
        seed: u64,
        with_phase: bool,
    ) -> Result<Vec<BoardCapture>, TwinError> {
        let k = &self.rig.projectors[0].model.intrinsics;
        let (w, h) = (k.width, k.height);
        let white = Arc::new(Pattern::flat(w, h, 1.0));
        let fringes: Vec<Vec<Arc<Pattern>>> = if with_phase {
            [0.0, 0.5 * std::f64::consts::PI]
                .iter()
                .map(|&angle_rad| fringe_patterns(w, h, angle_rad))
                .collect()
        } else {
            Vec::new()
        };
        let mut captures = Vec::with_capacity(self.world_from_board.len());
        for v in 0..self.world_from_board.len() {
            let scene = self.scene(v);
            let board_renderer =
                Renderer::with_pixel_samples(&scene, &self.rig, 0, 0.0, self.pixel_samples)?;
            let view_seed = seed.wrapping_mul(7919).wrapping_add(1000 * v as u64);
            let image = expose(&board_renderer, &white, sensor, view_seed)?;
            let phase = if with_phase {
                // One ray per pixel for the fringes: on the flat board the phase is
                // smooth and the albedo edges cancel in it, so area sampling (16x the
                // cost for 24 frames) changes nothing the phase maps are used for.
                let renderer = Renderer::new(&scene, &self.rig, 0, 0.0)?;
                let mut maps = Vec::with_capacity(2);
                for (d, (patterns, range_px)) in fringes.iter().zip([w, h]).enumerate() {
                    let mut frames = Vec::with_capacity(patterns.len());
                    for (i, p) in patterns.iter().enumerate() {
                        let s = view_seed + 1 + (d * patterns.len() + i) as u64;
                        frames.push(expose(&renderer, p, sensor, s)?);
                    }
                    maps.push(absolute_phase(&frames, f64::from(range_px)));
                }
                let y = maps.pop().expect("two maps");
                let x = maps.pop().expect("two maps");
                Some((x, y))
            } else {
                None
            };
            captures.push(BoardCapture {
                name: format!("view_{v:02}"),
                image,
                phase,
            });
        }
        Ok(captures)
    }
}

/// `STEPS` shifted fringes per period of [`PERIODS_PX`], period-major.
fn fringe_patterns(w: u32, h: u32, angle_rad: f64) -> Vec<Arc<Pattern>> {
    PERIODS_PX
        .iter()
        .flat_map(|&period_px| {
            (0..STEPS).map(move |n| {
                let f = Fringe {
                    period_px,
                    angle_rad,
                    shift_rad: TAU * n as f64 / STEPS as f64,
                };
                Arc::new(Pattern::fringe(w, h, &f, BitDepth::Eight))
            })
        })
        .collect()
}

/// The noisy camera image of `pattern` shown for the whole exposure, grey [0, 1].
fn expose(
    renderer: &Renderer,
    pattern: &Arc<Pattern>,
    sensor: &SensorModel,
    seed: u64,
) -> Result<GrayImage, TwinError> {
    let shown = [ProjectorTimeline::single(pattern.clone(), 0.0, EXPOSURE_S)];
    let exposure = Exposure {
        start_s: 0.0,
        end_s: EXPOSURE_S,
    };
    let (image, _) = renderer.image(&shown, exposure, sensor, seed)?;
    let luma: Vec<f32> = image
        .data
        .chunks(image.channels)
        .map(|c| c.iter().sum::<f32>() / c.len() as f32)
        .collect();
    Ok(GrayImage::from_raw(image.width, image.height, luma).expect("width x height samples"))
}

/// Absolute phase of the finest period from `STEPS x PERIODS_PX` frames, NaN where the
/// modulation is too low or the heterodyne check refuses the pixel.
fn absolute_phase(frames: &[GrayImage], range_px: f64) -> GrayImage {
    let (w, h) = frames[0].dimensions();
    let rasters: Vec<Raster<f32>> = frames
        .iter()
        .map(|f| Raster::from_vec(w as usize, h as usize, f.as_raw().clone()).expect("size"))
        .collect();
    let shift = PhaseShift::new(STEPS).expect("4 steps");
    let wrapped: Vec<WrappedPhase> = rasters
        .chunks(STEPS)
        .map(|c| {
            let refs: Vec<&Raster<f32>> = c.iter().collect();
            shift.wrapped_phase(&refs).expect("equal sizes")
        })
        .collect();
    // Low floor: dark squares (reflectance 0.06) must keep their phase for the corner
    // windows; the heterodyne residual check refuses pixels too noisy to unwrap.
    let mask = Raster::from_fn(w as usize, h as usize, |x, y| {
        wrapped.iter().all(|p| *p.modulation.at(x, y) >= 0.008)
    });
    let unwrapper = Heterodyne::new(&PERIODS_PX, range_px, std::f64::consts::FRAC_PI_2)
        .expect("periods span the DMD");
    let refs: Vec<&Raster<f32>> = wrapped.iter().map(|p| &p.phase).collect();
    let abs = unwrapper.unwrap(&refs, Some(&mask)).expect("equal sizes");
    GrayImage::from_raw(w, h, abs.phase.data).expect("width x height samples")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::PinholeModel;

    #[test]
    fn board_pose_maps_corner_zero_to_the_twins_first_inner_corner() {
        let sim = TwinHead::standard(2, &Detail::default());
        let camera = &sim.rig.cameras[0].model;
        for v in 0..2 {
            let want = CHECKERBOARD.corners_px(&sim.world_from_board[v], camera);
            let model = PinholeModel {
                pose: sim.board_pose(v),
                ..sim.truth.camera
            };
            let flipped = PinholeModel {
                pose: sim.flipped_board_pose(v),
                ..sim.truth.camera
            };
            let corners = board().corners_m();
            for (i, c) in corners.iter().enumerate() {
                let p = nalgebra::Point3::new(c.x, c.y, 0.0);
                let got = model.project(&p).unwrap();
                let t = want[i].unwrap();
                assert!((got.x - t[0]).abs() < 1e-9 && (got.y - t[1]).abs() < 1e-9);
                let got = flipped.project(&p).unwrap();
                let t = want[corners.len() - 1 - i].unwrap();
                assert!((got.x - t[0]).abs() < 1e-9 && (got.y - t[1]).abs() < 1e-9);
            }
        }
    }
}

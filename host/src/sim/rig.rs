//! The simulated rig: hil-sim's board served on a real pseudo-terminal, the
//! host's serial [`crate::board::BoardClient`] talking to it (through
//! [`crate::rig::serial_board::SerialBoard`], as on hardware), and cameras
//! rendered by the digital twin ([`TwinRig`]).
//!
//! A camera frame is rendered from the board's executed timeline, not from
//! the plan: each simulated DMD logs when each pattern was really on its
//! mirrors (after trigger latency and jitter), each simulated camera when
//! its shutter was really open, and the twin integrates exactly that light.
//! A sequencing error therefore shows up in the images.

use std::path::Path;
use std::sync::Arc;

use hil_sim::board::{spawn_board_on_pty, SimBoard, SimBoardConfig, SimBoardHandle};
use hil_sim::devices::{patterns_in_window, Displayed};
use hil_sim::twin::{
    Display, Exposure, Image, Pattern, ProjectorTimeline, SensorModel, Shown, TwinRig,
};
use protocol::ScanPlan;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::dlpc::{shown, simulated_head, SimHidLink};
use crate::board::{ClientConfig, ScanOutcome};
use crate::raster::Raster;
use crate::rig::dlpc::{Controller, DlpcHead, DriverConfig};
use crate::rig::serial_board::SerialBoard;
use crate::rig::{check_sequence, slots_per_frame, Board, Camera, Led, Projector, RigError, WHITE};

/// How to build a [`SimRig`].
#[derive(Clone, Debug)]
pub struct SimRigConfig {
    /// The simulated board (seed of device jitter, injected faults).
    pub board: SimBoardConfig,
    /// Timeouts of the host's client.
    pub client: ClientConfig,
    /// Sensor model of every camera.
    pub sensor: SensorModel,
    /// Seed of the cameras' noise.
    pub noise_seed: u64,
    /// The simulated board's lines (`BoardLimits::STM32G474`: 4 trigger
    /// and 4 feedback lines, two heads; a rig of three or four heads needs
    /// a board with 8).
    pub board_limits: protocol::BoardLimits,
}

/// Board on a pty + twin cameras. Head `h` is the twin's camera `h` and
/// projector `h`, wired as board head `h` of the plan.
pub struct SimRig {
    // Dropped before the board (field order): the board outlives its link.
    board_link: SerialBoard,
    board: SimBoardHandle,
    twin: Arc<TwinRig>,
    sequences: Vec<Vec<Arc<Pattern>>>,
    /// Per head, the LEDs of each pattern of `sequences`.
    leds: Vec<Vec<Led>>,
    sensor: SensorModel,
    rng: ChaCha8Rng,
    /// Per head, per camera trigger of the last plan: patterns its exposure holds.
    slots_per_frame: Vec<Vec<usize>>,
    /// Per projector, the DLPC driver and simulated controller its patterns
    /// go through ([`SimRig::drive_projectors_through`]); empty: patterns
    /// go straight to the DMD.
    drivers: Vec<DlpcHead<SimHidLink>>,
}

impl SimRig {
    /// Starts a simulated board on a pty and connects the host's serial
    /// client to it (handshake done).
    pub fn start(twin: Arc<TwinRig>, config: SimRigConfig) -> Result<Self, RigError> {
        let board = spawn_board_on_pty(SimBoard::with_limits(config.board, config.board_limits))
            .map_err(|e| RigError::Backend {
                what: "simulated board on a pty".into(),
                source: Box::new(e),
            })?;
        let path = board.path().unwrap_or(Path::new("")).to_path_buf();
        let board_link = SerialBoard::open(&path, config.client)?;
        let heads = twin.rig().cameras.len();
        Ok(SimRig {
            board_link,
            board,
            sequences: vec![Vec::new(); twin.rig().projectors.len()],
            leds: vec![Vec::new(); twin.rig().projectors.len()],
            twin,
            sensor: config.sensor,
            rng: ChaCha8Rng::seed_from_u64(config.noise_seed),
            slots_per_frame: vec![Vec::new(); heads],
            drivers: Vec::new(),
        })
    }

    /// From now on every projector's patterns go through the real
    /// `controller` driver (`crate::rig::dlpc`) as USB HID reports to
    /// hil-sim's byte-level controller, and the DMD shows what that
    /// controller holds (8-bit grey or 1-bit planes, LEDs on or off).
    /// The simulated controller's DMD has the twin projector's size; its
    /// other limits are the real controller's. `exposure_us` is the LUT's
    /// exposure (the board's plan still times each pattern).
    pub fn drive_projectors_through(&mut self, controller: Controller, exposure_us: u32) {
        self.drivers = self
            .twin
            .rig()
            .projectors
            .iter()
            .map(|p| {
                let k = &p.model.intrinsics;
                simulated_head(
                    controller,
                    (k.width, k.height),
                    DriverConfig::new(exposure_us),
                )
            })
            .collect();
    }

    /// The drivers of [`SimRig::drive_projectors_through`], one per projector.
    pub fn drivers(&self) -> &[DlpcHead<SimHidLink>] {
        &self.drivers
    }

    /// The twin the cameras render.
    pub fn twin(&self) -> &TwinRig {
        &self.twin
    }

    fn check_head(&self, head: usize) -> Result<(), RigError> {
        let heads = self.twin.rig().cameras.len();
        if head >= heads || head >= self.twin.rig().projectors.len() {
            return Err(RigError::NoSuchHead { head, heads });
        }
        Ok(())
    }

    /// What each projector really displayed in the last plan, as twin timelines.
    fn timelines(&self) -> Vec<ProjectorTimeline> {
        let board = self.board.board();
        let sim_heads = board.hardware().heads();
        (0..self.twin.rig().projectors.len())
            .map(|p| {
                let shown = match (sim_heads.get(p), self.sequences.get(p)) {
                    (Some(head), Some(seq)) if !seq.is_empty() => {
                        timeline(head.projector.displayed(), seq, &self.leds[p])
                    }
                    _ => Vec::new(),
                };
                ProjectorTimeline { shown }
            })
            .collect()
    }
}

/// The displayed log of one DMD as twin `Shown` items (virtual ns -> s);
/// the DMD steps through its table (and its LED table, `leds`, one per
/// pattern) once per accepted trigger.
fn timeline(displayed: &[Displayed], sequence: &[Arc<Pattern>], leds: &[Led]) -> Vec<Shown> {
    displayed
        .iter()
        .map(|d| {
            let k = d.pattern_index as usize % sequence.len();
            Shown {
                pattern: sequence[k].clone(),
                start_s: d.start_ns as f64 * 1e-9,
                end_s: d.end_ns as f64 * 1e-9,
                led: leds.get(k).copied().unwrap_or(WHITE),
                display: Display::Steady,
            }
        })
        .collect()
}

/// From the board-clock timestamps alone: frame `i` must hold exactly the
/// next `slots[i]` patterns of the DMD's sequence, each shown whole while
/// the shutter was open (what the plan asks for).
fn check_sequencing(
    head: usize,
    windows_ns: &[(u64, u64)],
    displayed: &[Displayed],
    slots: &[usize],
) -> Result<(), RigError> {
    let mut next = 0usize;
    for (frame, (&(start_ns, end_ns), &count)) in windows_ns.iter().zip(slots).enumerate() {
        let seen = patterns_in_window(displayed, start_ns, end_ns);
        let want: Vec<u32> = (next..next + count).map(|i| i as u32).collect();
        let got: Vec<u32> = seen.iter().map(|s| s.0).collect();
        let whole = seen.iter().all(|&(i, overlap_ns)| {
            displayed
                .get(i as usize)
                .is_some_and(|d| d.end_ns - d.start_ns == overlap_ns)
        });
        if got != want || !whole {
            return Err(RigError::Sequencing {
                head,
                frame,
                expected: want,
                seen,
            });
        }
        next += count;
    }
    Ok(())
}

impl Board for SimRig {
    fn run_plan(&mut self, plan: &ScanPlan) -> Result<ScanOutcome, RigError> {
        self.check_plan(plan)?;
        self.slots_per_frame = slots_per_frame(plan, self.slots_per_frame.len());
        self.board_link.run_plan(plan)
    }

    fn limits(&self) -> Option<protocol::BoardLimits> {
        self.board_link.limits()
    }
}

impl Projector for SimRig {
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.check_head(head)?;
        let k = &self.twin.rig().projectors[head].model.intrinsics;
        Ok((k.width, k.height))
    }

    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        self.load_coloured_sequence(head, patterns, &vec![WHITE; patterns.len()])
    }

    /// Through DLPC drivers, what the simulated controllers hold bounds the
    /// plan as on hardware; straight to the DMDs, every plan goes.
    fn check_plan(&self, plan: &ScanPlan) -> Result<(), RigError> {
        crate::rig::dlpc::check_plan_on_heads(&self.drivers, plan)
    }

    fn load_coloured_sequence(
        &mut self,
        head: usize,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<(), RigError> {
        let expected = self.dmd_size_px(head)?;
        check_sequence(head, expected, patterns, leds)?;
        if let Some(driver) = self.drivers.get_mut(head) {
            self.sequences[head] = Vec::new();
            driver
                .load(patterns, leds)
                .map_err(|source| RigError::Controller { head, source })?;
            let on_dmd = shown(driver);
            self.leds[head] = on_dmd
                .iter()
                .map(|p| p.led.map(|on| if on { 1.0 } else { 0.0 }))
                .collect();
            self.sequences[head] = on_dmd
                .into_iter()
                .map(|p| {
                    Arc::new(Pattern {
                        width: expected.0,
                        height: expected.1,
                        values: p.values,
                    })
                })
                .collect();
            return Ok(());
        }
        let mut seq = Vec::with_capacity(patterns.len());
        for p in patterns {
            seq.push(Arc::new(Pattern {
                width: expected.0,
                height: expected.1,
                values: p.data.clone(),
            }));
        }
        self.sequences[head] = seq;
        self.leds[head] = leds.to_vec();
        Ok(())
    }
}

impl Camera for SimRig {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.check_head(head)?;
        let k = &self.twin.rig().cameras[head].model.intrinsics;
        Ok((k.width, k.height))
    }

    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        let (w, h) = self.image_size_px(head)?;
        let frames = self.render_frames(head)?;
        Ok(frames
            .into_iter()
            .map(|image| {
                // A colour sensor's frame read as grey: the channels' mean.
                let data = if image.channels == 1 {
                    image.data
                } else {
                    image
                        .data
                        .chunks(image.channels)
                        .map(|c| c.iter().sum::<f32>() / c.len() as f32)
                        .collect()
                };
                Raster {
                    width: w as usize,
                    height: h as usize,
                    data,
                }
            })
            .collect())
    }

    /// The twin camera's R, G and B channels; a mono [`SimRigConfig::sensor`]
    /// gives [`RigError::NotColour`].
    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        let (w, h) = self.image_size_px(head)?;
        if self.sensor.channels.count() != 3 {
            return Err(RigError::NotColour { head });
        }
        let frames = self.render_frames(head)?;
        Ok(frames
            .into_iter()
            .map(|image| {
                [0, 1, 2].map(|c| Raster {
                    width: w as usize,
                    height: h as usize,
                    data: image.data.iter().skip(c).step_by(3).copied().collect(),
                })
            })
            .collect())
    }
}

impl SimRig {
    /// Head `head`'s camera frames of the last plan as the twin's sensor
    /// images (1 or 3 channels), after checking that the board triggered
    /// every frame and showed every pattern where the plan puts it.
    fn render_frames(&mut self, head: usize) -> Result<Vec<Image>, RigError> {
        self.check_head(head)?;
        let expected = self.slots_per_frame[head].len();
        let expected_patterns: usize = self.slots_per_frame[head].iter().sum();
        let (exposures, missed, displayed) = {
            let board = self.board.board();
            let sim = board
                .hardware()
                .heads()
                .get(head)
                .ok_or(RigError::NoSuchHead {
                    head,
                    heads: board.hardware().heads().len(),
                })?;
            (
                sim.camera.exposures().to_vec(),
                sim.camera.missed().iter().map(|m| m.0).collect::<Vec<_>>(),
                sim.projector.displayed().to_vec(),
            )
        };
        let done: Vec<_> = exposures
            .iter()
            .filter_map(|e| e.end_ns.map(|end| (e.start_ns, end)))
            .collect();
        if done.len() != expected || !missed.is_empty() {
            return Err(RigError::FrameCount {
                head,
                expected,
                got: done.len(),
                missed,
            });
        }
        if displayed.len() != expected_patterns {
            return Err(RigError::PatternCount {
                head,
                expected: expected_patterns,
                got: displayed.len(),
            });
        }
        check_sequencing(head, &done, &displayed, &self.slots_per_frame[head])?;
        let timelines = self.timelines();
        let mut frames = Vec::with_capacity(done.len());
        for (start_ns, end_ns) in done {
            let window = Exposure {
                start_s: start_ns as f64 * 1e-9,
                end_s: end_ns as f64 * 1e-9,
            };
            let (image, _saturated) = self
                .twin
                .image(head, &timelines, window, &self.sensor, &mut self.rng)
                .map_err(|e| RigError::Backend {
                    what: format!("twin camera {head}"),
                    source: Box::new(e),
                })?;
            frames.push(image);
        }
        Ok(frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shown(pattern_index: u32, start_ns: u64, end_ns: u64) -> Displayed {
        Displayed {
            pattern_index,
            trigger_ns: start_ns,
            start_ns,
            end_ns,
        }
    }

    #[test]
    fn each_frame_must_hold_its_own_patterns_whole() {
        let windows = [(0, 100), (200, 300)];
        let good = [shown(0, 10, 90), shown(1, 210, 290)];
        check_sequencing(0, &windows, &good, &[1, 1]).unwrap();
        // Pattern 1 lights up late and spills past the shutter.
        let late = [shown(0, 10, 90), shown(1, 250, 330)];
        let err = check_sequencing(1, &windows, &late, &[1, 1]).unwrap_err();
        assert!(
            matches!(err, RigError::Sequencing { head: 1, frame: 1, ref seen, .. } if seen == &[(1, 50)]),
            "{err}"
        );
        // Pattern 0 lingers into the next frame.
        let lingering = [shown(0, 10, 210), shown(1, 215, 290)];
        assert!(check_sequencing(0, &windows, &lingering, &[1, 1]).is_err());
    }

    /// A simulated head of the `plane` scene with `sensor`, R, G and B
    /// floods loaded and run, one short exposure each.
    fn floods_taken(sensor: SensorModel) -> SimRig {
        use crate::scan::plan::{one_pattern_per_scaled_exposure, MIN_EXPOSURE_SCALE};
        use hil_sim::twin::scenes::{built_in, Detail};
        let detail = Detail {
            camera: (48, 36),
            projector: (64, 40),
        };
        let (scene, rig) = built_in("plane", &detail).unwrap();
        let twin = Arc::new(TwinRig::new(scene, rig).unwrap());
        let mut sim = SimRig::start(
            twin,
            SimRigConfig {
                board: SimBoardConfig::default(),
                client: ClientConfig::default(),
                sensor,
                noise_seed: 1,
                board_limits: protocol::BoardLimits::STM32G474,
            },
        )
        .unwrap();
        let white = Raster::filled(64, 40, 1.0f32);
        let leds = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        sim.load_coloured_sequence(0, &[white.clone(), white.clone(), white], &leds)
            .unwrap();
        // 1/32 of the standard exposure: a white flood stays below full scale.
        let plan =
            one_pattern_per_scaled_exposure(protocol::HeadSet::A, 3, MIN_EXPOSURE_SCALE).unwrap();
        crate::rig::require_clean(&sim.run_plan(&plan).unwrap()).unwrap();
        sim
    }

    #[test]
    fn colour_frames_split_the_channels_that_grey_frames_average() {
        // colour8 without noise, so both takes render the same images.
        let sensor = SensorModel {
            shot_noise: false,
            read_noise_e: 0.0,
            ..SensorModel::colour8()
        };
        let mut sim = floods_taken(sensor);
        let colour = sim.take_colour_frames(0).unwrap();
        let grey = sim.take_frames(0).unwrap();
        assert_eq!((colour.len(), grey.len()), (3, 3));
        let mean = |r: &Raster<f32>| r.data.iter().sum::<f32>() / r.data.len() as f32;
        for (led, (planes, g)) in colour.iter().zip(&grey).enumerate() {
            let m = planes.each_ref().map(mean);
            assert!(m[led] > 0.1 && m[led] < 0.9, "LED {led}: {m:?}");
            // colour8's crosstalk into the other channels is at most 0.15 / 0.85.
            for (c, v) in m.iter().enumerate() {
                assert!(c == led || *v < 0.3 * m[led], "LED {led}: {m:?}");
            }
            for p in planes {
                assert_eq!(p.size(), (48, 36));
            }
            for (i, v) in g.data.iter().enumerate() {
                let sum = planes[0].data[i] + planes[1].data[i] + planes[2].data[i];
                assert_eq!(*v, sum / 3.0);
            }
        }
    }

    #[test]
    fn a_mono_camera_gives_no_colour_frames() {
        let mut sim = floods_taken(SensorModel::mono12());
        let err = sim.take_colour_frames(0).unwrap_err();
        assert!(matches!(err, RigError::NotColour { head: 0 }), "{err}");
        assert!(err.to_string().contains("no colour frames"), "{err}");
        assert_eq!(sim.take_frames(0).unwrap().len(), 3);
        assert!(matches!(
            sim.take_colour_frames(2),
            Err(RigError::NoSuchHead { head: 2, .. })
        ));
    }
}

//! ZOCR-Net (seed 001's first stage) on tract: the camera's colour long
//! exposure in, each LED's fringes without the zero order and without the
//! camera's colour crosstalk out, with the zero order itself, so the
//! demultiplexer's carrier demodulation ([`super::demux`]) takes over from
//! there. The learned replacement of [`super::Demultiplexer::remove_zero_order`].

use std::path::Path;

use super::demux::ZeroOrderRemoved;
use super::learned::{self, LearnedStage};
use super::set::PatternSet;
use super::HighSpeedError;
use crate::infer::tiles::{infer_tiled, Planes};
use crate::infer::{Model, ModelError};

/// Camera channels in (R, G, B).
pub const IN_CHANNELS: usize = 3;
/// Out: per LED the fringes, then per LED the zero order.
pub const OUT_CHANNELS: usize = 6;
/// Tiles overlap by this much (the network sees about 33 px).
const TILE_OVERLAP_PX: usize = 24;

/// A loaded ZOCR-Net.
#[derive(Clone, Debug)]
pub struct ZocrNet {
    model: Model,
}

impl LearnedStage for ZocrNet {
    const NAME: &'static str = "ZOCR-Net";
    const TILE_OVERLAP_PX: usize = TILE_OVERLAP_PX;

    fn model(&self) -> &Model {
        &self.model
    }
}

impl ZocrNet {
    /// Loads `onnx` (and its metadata) and checks it was trained for `set`'s
    /// patterns (their DMD periods, in order) with this channel layout.
    pub fn load(onnx: &Path, set: &PatternSet) -> Result<Self, HighSpeedError> {
        Ok(Self {
            model: learned::load_stage(onnx, set, "ZOCR-Net", IN_CHANNELS, OUT_CHANNELS)?,
        })
    }

    /// One exposure (camera R, G, B, row-major, full scale 1) -> each LED's
    /// fringes and zero order.
    pub fn remove_zero_order(
        &self,
        channels: [&[f32]; 3],
        width: usize,
        height: usize,
    ) -> Result<ZeroOrderRemoved, ModelError> {
        let plane = width * height;
        let data: Vec<f32> = channels.iter().flat_map(|c| c.iter().copied()).collect();
        let planes = Planes {
            data: &data,
            channels: IN_CHANNELS,
            width,
            height,
        };
        let tiled = infer_tiled(
            &planes,
            &vec![true; plane],
            self.model.meta.tile,
            Self::TILE_OVERLAP_PX,
            OUT_CHANNELS,
            |_, tile| self.model.run(&[tile]),
        )?;
        let out = |k: usize| tiled.data[k * plane..(k + 1) * plane].to_vec();
        Ok(ZeroOrderRemoved {
            fringes: [out(0), out(1), out(2)],
            zero_order: [out(3), out(4), out(5)],
        })
    }
}

//! hil-sim's byte-level DMD controller ([`hil_sim::devices::dlpc`]) as a
//! [`HidLink`]: the real driver (`crate::rig::dlpc`) talks to it report by
//! report, and the simulated rig lights its DMDs with what the controller
//! then shows.

use hil_sim::devices::dlpc::{ControllerPattern, DlpcKind, DlpcSim};
use protocol::ControllerLimits;

use crate::rig::dlpc::report::{REPLY_LEN, REPORT_LEN};
use crate::rig::dlpc::{Controller, DlpcHead, DriverConfig, HidLink, LinkError};

/// A simulated controller on an in-process "USB" link.
pub struct SimHidLink {
    device: DlpcSim,
}

impl SimHidLink {
    /// A simulated `controller` with `limits`.
    pub fn new(controller: Controller, limits: ControllerLimits) -> Self {
        let kind = match controller {
            Controller::Dlpc350 => DlpcKind::Dlpc350,
            Controller::Dlpc900 => DlpcKind::Dlpc900,
        };
        SimHidLink {
            device: DlpcSim::new(kind, limits),
        }
    }

    /// The device (its images, LUT, what it shows).
    pub fn device(&self) -> &DlpcSim {
        &self.device
    }

    /// The device, to throw its fault switch.
    pub fn device_mut(&mut self) -> &mut DlpcSim {
        &mut self.device
    }
}

impl HidLink for SimHidLink {
    fn write(&mut self, report: &[u8; REPORT_LEN]) -> Result<(), LinkError> {
        self.device
            .write(report)
            .map_err(|_| LinkError::Disconnected)
    }

    fn read(&mut self, timeout_ms: u32) -> Result<[u8; REPLY_LEN], LinkError> {
        // The simulated controller answers at once or never.
        match self.device.read() {
            Ok(Some(r)) => Ok(r),
            Ok(None) => Err(LinkError::Timeout { timeout_ms }),
            Err(_) => Err(LinkError::Disconnected),
        }
    }
}

/// A driver for `controller` on a simulated one whose DMD is `dmd_px` (the
/// twin projector's size; every other limit is the real controller's).
pub fn simulated_head(
    controller: Controller,
    dmd_px: (u32, u32),
    config: DriverConfig,
) -> DlpcHead<SimHidLink> {
    let limits = ControllerLimits {
        dmd_px: (dmd_px.0 as u16, dmd_px.1 as u16),
        ..controller.model().controller()
    };
    DlpcHead::with_limits(
        SimHidLink::new(controller, limits),
        controller,
        limits,
        config,
    )
}

/// What the controller behind `head` shows, in trigger order.
pub fn shown(head: &DlpcHead<SimHidLink>) -> Vec<ControllerPattern> {
    head.link().device().sequence()
}

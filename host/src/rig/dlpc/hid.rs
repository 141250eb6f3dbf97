//! A real controller through hidapi (cargo feature `hid`; Linux uses
//! hidapi's pure-Rust hidraw back end with basic-udev, so no libudev is
//! needed to build). Not tested on hardware: no device here.

use hidapi::{HidApi, HidDevice};

use super::report::{REPLY_LEN, REPORT_LEN};
use super::{Controller, HidLink, LinkError, DLPC350_PRODUCT_ID, DLPC900_PRODUCT_ID, TI_VENDOR_ID};

/// One controller opened through hidapi.
pub struct HidapiLink {
    device: HidDevice,
}

/// A controller found on the USB bus.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Found {
    /// Which controller its product id names.
    pub controller: Controller,
    /// Its serial number, if it reports one.
    pub serial: Option<String>,
    /// The interface number (the DLPC900's pattern interface is 0).
    pub interface: i32,
}

fn backend(e: hidapi::HidError) -> LinkError {
    LinkError::Backend(Box::new(e))
}

/// Every DLPC350 / DLPC900 on the bus.
pub fn list() -> Result<Vec<Found>, LinkError> {
    let api = HidApi::new().map_err(backend)?;
    Ok(api
        .device_list()
        .filter(|d| d.vendor_id() == TI_VENDOR_ID)
        .filter_map(|d| {
            let controller = match d.product_id() {
                DLPC350_PRODUCT_ID => Controller::Dlpc350,
                DLPC900_PRODUCT_ID => Controller::Dlpc900,
                _ => return None,
            };
            Some(Found {
                controller,
                serial: d.serial_number().map(str::to_string),
                interface: d.interface_number(),
            })
        })
        .collect())
}

impl HidapiLink {
    /// Opens the first `controller`, or the one with `serial`.
    pub fn open(controller: Controller, serial: Option<&str>) -> Result<Self, LinkError> {
        let api = HidApi::new().map_err(backend)?;
        let pid = match controller {
            Controller::Dlpc350 => DLPC350_PRODUCT_ID,
            Controller::Dlpc900 => DLPC900_PRODUCT_ID,
        };
        let device = match serial {
            Some(s) => api.open_serial(TI_VENDOR_ID, pid, s),
            None => api.open(TI_VENDOR_ID, pid),
        }
        .map_err(backend)?;
        Ok(HidapiLink { device })
    }
}

impl HidLink for HidapiLink {
    fn write(&mut self, report: &[u8; REPORT_LEN]) -> Result<(), LinkError> {
        match self.device.write(report) {
            Ok(_) => Ok(()),
            Err(e) => Err(backend(e)),
        }
    }

    fn read(&mut self, timeout_ms: u32) -> Result<[u8; REPLY_LEN], LinkError> {
        let mut buf = [0u8; REPLY_LEN];
        let n = self
            .device
            .read_timeout(&mut buf, timeout_ms.min(i32::MAX as u32) as i32)
            .map_err(backend)?;
        if n == 0 {
            return Err(LinkError::Timeout { timeout_ms });
        }
        Ok(buf)
    }
}

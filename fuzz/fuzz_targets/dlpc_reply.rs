//! Any bytes as DLPC350 / DLPC900 replies (a device's answers are input
//! from outside the program): straight into
//! `slscan::rig::dlpc::report::parse_reply`, and as the 64-byte reports a
//! scripted link answers the whole driver with (version, status, error
//! code, a small upload). No panic; a parsed reply's data lies inside the
//! report; a load that succeeds was acknowledged message by message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::{ControllerLimits, ProjectorModel};
use slscan::raster::Raster;
use slscan::rig::dlpc::report::{parse_reply, REPLY_LEN, REPORT_LEN};
use slscan::rig::dlpc::{Controller, DlpcHead, DriverConfig, HidLink, LinkError};

/// Answers each read with the next 64 bytes of the input (zero-padded), then
/// times out.
struct Scripted<'a> {
    replies: std::slice::Chunks<'a, u8>,
}

impl HidLink for Scripted<'_> {
    fn write(&mut self, _report: &[u8; REPORT_LEN]) -> Result<(), LinkError> {
        Ok(())
    }

    fn read(&mut self, timeout_ms: u32) -> Result<[u8; REPLY_LEN], LinkError> {
        let chunk = self
            .replies
            .next()
            .ok_or(LinkError::Timeout { timeout_ms })?;
        let mut r = [0u8; REPLY_LEN];
        r[..chunk.len()].copy_from_slice(chunk);
        Ok(r)
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&seq, rest)) = data.split_first() else {
        return;
    };
    for expected in [None, Some(seq)] {
        if let Ok(r) = parse_reply(rest, expected) {
            assert!(r.data.len() + 4 <= rest.len());
        }
    }
    let controller = if seq & 1 == 0 {
        Controller::Dlpc350
    } else {
        Controller::Dlpc900
    };
    let limits = ControllerLimits {
        dmd_px: (8, 4),
        ..ProjectorModel::Dlpc900.controller()
    };
    let link = Scripted {
        replies: rest.chunks(REPLY_LEN),
    };
    let mut head = DlpcHead::with_limits(link, controller, limits, DriverConfig::new(10_000));
    let _ = head.version();
    let _ = head.status();
    let _ = head.error_code();
    let set = vec![Raster::filled(8, 4, 0.5); 4];
    if let Ok(stats) = head.load(&set, &[[1.0; 3]; 4]) {
        assert_eq!(stats.reports_in, stats.messages);
        assert_eq!(head.loaded(), Some(stats));
    } else {
        assert_eq!(head.loaded(), None);
    }
});

//! GenICam cameras through Aravis 0.8 (cargo feature `genicam`).
//!
//! One [`GenicamCamera`] per head: opened by id, configured once (pixel
//! format, region, exposure and gain with the auto modes off, frame-start
//! trigger on the board's line), then acquiring continuously into a buffer
//! pool; a plan is [`GenicamCamera::arm`]ed (frames queued before it are
//! dropped) and its frames [`GenicamCamera::take_frames`]n after it ran,
//! checked by [`super::ledger`]. [`GenicamCameras`] is the rig's
//! [`FrameSource`] over them.

use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

use aravis::glib::prelude::Cast;
use aravis::prelude::*;
use aravis::{
    AcquisitionMode, Aravis, Auto, Buffer, BufferStatus, Camera, GvStream, GvStreamOption,
    GvStreamPacketResend, GvStreamSocketBuffer, Stream,
};

use super::ledger::{check_arrivals, Arrival, ArrivalStatus};
use super::pixels::{decode_colour_frame, decode_frame, PixelFormat};
use super::{CameraInfo, GenicamError, GenicamSettings, StreamCounters};
use crate::raster::Raster;
use crate::rig::camera_source::FrameSource;
use crate::rig::RigError;

/// Aravis's global device list is not thread-safe; its token lives here.
fn aravis() -> &'static Mutex<Option<Aravis>> {
    static TOKEN: OnceLock<Mutex<Option<Aravis>>> = OnceLock::new();
    TOKEN.get_or_init(|| Mutex::new(Aravis::initialize().ok()))
}

/// The GenICam cameras Aravis finds now (GigE Vision on every interface,
/// USB3 Vision).
pub fn list_cameras() -> Vec<CameraInfo> {
    let guard = aravis().lock().unwrap_or_else(|e| e.into_inner());
    let Some(token) = guard.as_ref() else {
        return Vec::new();
    };
    token
        .get_device_list()
        .into_iter()
        .map(|d| CameraInfo {
            id: d.id.to_string_lossy().into_owned(),
            vendor: d.vendor.to_string_lossy().into_owned(),
            model: d.model.to_string_lossy().into_owned(),
            protocol: d.protocol.to_string_lossy().into_owned(),
            address: d.address.to_string_lossy().into_owned(),
        })
        .collect()
}

/// Camera `id`'s firmware version, read by opening it without touching
/// its settings (`DeviceFirmwareVersion`, else `DeviceVersion`).
pub fn describe(id: &str) -> Result<String, GenicamError> {
    let camera = Camera::new(Some(id)).map_err(device_error(id, "open"))?;
    Ok(firmware_of(&camera))
}

fn firmware_of(camera: &Camera) -> String {
    ["DeviceFirmwareVersion", "DeviceVersion"]
        .iter()
        .find_map(|f| camera.string(f).ok())
        .map(|s| s.to_string())
        .unwrap_or_default()
}

/// One camera, configured and acquiring.
pub struct GenicamCamera {
    id: String,
    camera: Camera,
    stream: Stream,
    format: PixelFormat,
    size: (u32, u32),
    frame_timeout: Duration,
    firmware: String,
    expected: usize,
    counters_at_arm: StreamCounters,
    last_arrivals: Vec<Arrival>,
    last_counters: StreamCounters,
}

impl GenicamCamera {
    /// Opens camera `id` (see [`list_cameras`]) and starts it acquiring
    /// with `settings`; every refused step is an error naming it.
    pub fn open(id: &str, settings: &GenicamSettings) -> Result<GenicamCamera, GenicamError> {
        let found = list_cameras();
        let Some(info) = found.iter().find(|c| c.id == id) else {
            return Err(GenicamError::NotFound {
                id: id.into(),
                found: found.into_iter().map(|c| c.id).collect(),
            });
        };
        let fail = |step: &str| device_error(id, step);
        let camera = Camera::new(Some(id)).map_err(fail("open"))?;
        if camera.is_gv_device() && info.address.starts_with("127.") {
            // Linux packet sockets do not see loopback traffic; a camera
            // served on 127.0.0.1 (the fake GigE Vision camera) needs the
            // plain UDP socket.
            camera.gv_set_stream_options(GvStreamOption::PACKET_SOCKET_DISABLED);
        }
        configure(&camera, id, settings)?;
        let (_, _, width, height) = camera.region().map_err(fail("read Width/Height"))?;
        let format = PixelFormat::from_name(
            camera
                .pixel_format_as_string()
                .map_err(fail("read PixelFormat"))?
                .as_str(),
        )
        .filter(|&f| f == settings.pixel_format)
        .ok_or_else(|| GenicamError::PixelFormat {
            id: id.into(),
            format: settings.pixel_format.name().into(),
            accepted: "the camera did not keep it".into(),
        })?;
        let payload = camera.payload().map_err(fail("read PayloadSize"))? as usize;
        let stream = camera.create_stream().map_err(fail("create stream"))?;
        if let Some(gv) = stream.downcast_ref::<GvStream>() {
            gv.set_socket_buffer(GvStreamSocketBuffer::Auto);
            gv.set_packet_resend(if settings.packet_resend {
                GvStreamPacketResend::Always
            } else {
                GvStreamPacketResend::Never
            });
        }
        for _ in 0..settings.buffers.max(2) {
            stream.push_buffer(Buffer::new_allocate(payload));
        }
        camera
            .start_acquisition()
            .map_err(fail("AcquisitionStart"))?;
        let firmware = firmware_of(&camera);
        let mut opened = GenicamCamera {
            id: id.into(),
            camera,
            stream,
            format,
            size: (width.max(0) as u32, height.max(0) as u32),
            frame_timeout: settings.frame_timeout,
            firmware,
            expected: 0,
            counters_at_arm: StreamCounters::default(),
            last_arrivals: Vec::new(),
            last_counters: StreamCounters::default(),
        };
        opened.counters_at_arm = opened.counters();
        Ok(opened)
    }

    /// The id it was opened by.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// `DeviceFirmwareVersion` (or `DeviceVersion`), empty when neither.
    pub fn firmware_version(&self) -> &str {
        &self.firmware
    }

    /// Image size (width, height), pixels.
    pub fn image_size_px(&self) -> (u32, u32) {
        self.size
    }

    /// The pixel format frames come in.
    pub fn pixel_format(&self) -> PixelFormat {
        self.format
    }

    /// The stream's counters since the camera was opened.
    pub fn counters(&self) -> StreamCounters {
        let get = |name: &str| self.stream.info_uint64_by_name(name);
        StreamCounters {
            completed: get("n_completed_buffers"),
            failures: get("n_failures"),
            resent_packets: get("n_resent_packets"),
            missing_packets: get("n_missing_packets"),
            resend_requests: get("n_resend_requests"),
        }
    }

    /// The next plan triggers this camera `frames` times: frames already
    /// queued belong to no scan of ours and are dropped.
    pub fn arm(&mut self, frames: usize) {
        while let Some(buffer) = self.stream.try_pop_buffer() {
            self.stream.push_buffer(buffer);
        }
        self.expected = frames;
        self.counters_at_arm = self.counters();
    }

    /// Sends one `TriggerSoftware` (cameras set to `TriggerSource =
    /// Software`: tests and benches without a board).
    pub fn software_trigger(&self) -> Result<(), GenicamError> {
        self.camera
            .software_trigger()
            .map_err(|e| GenicamError::Device {
                id: self.id.clone(),
                step: "TriggerSoftware".into(),
                message: e.message().to_owned(),
            })
    }

    /// The armed plan's frames, one per trigger in trigger order, values
    /// in [0, 1] (a colour format read as grey: its planes' mean): waits up
    /// to the frame time-out for each, then briefly for a late extra one (a
    /// double trigger).
    pub fn take_frames(&mut self) -> Result<Vec<Raster<f32>>, GenicamError> {
        self.take_decoded(decode_frame)
    }

    /// The armed plan's frames as [`GenicamCamera::take_frames`] takes
    /// them, each as its red, green and blue planes; a camera set to a
    /// monochrome format answers [`super::PixelError::NotColour`].
    pub fn take_colour_frames(&mut self) -> Result<Vec<[Raster<f32>; 3]>, GenicamError> {
        self.take_decoded(decode_colour_frame)
    }

    /// The armed plan's buffers, checked against its triggers, each
    /// decoded by `decode` (a pixel decoder of [`super::pixels`]).
    fn take_decoded<T>(
        &mut self,
        decode: fn(PixelFormat, u32, u32, &[u8]) -> Result<T, super::PixelError>,
    ) -> Result<Vec<T>, GenicamError> {
        let start = Instant::now();
        let mut arrivals = Vec::with_capacity(self.expected);
        let mut images = Vec::with_capacity(self.expected);
        let settle = (self.frame_timeout / 10).min(Duration::from_millis(100));
        loop {
            let wait = if arrivals.len() < self.expected {
                self.frame_timeout
            } else {
                settle
            };
            let Some(buffer) = self.stream.timeout_pop_buffer(wait.as_micros() as u64) else {
                break;
            };
            let arrival = arrival_of(&buffer);
            let image = (arrival.status == ArrivalStatus::Complete).then(|| {
                (
                    buffer.image_width(),
                    buffer.image_height(),
                    buffer.image_pixel_format().raw(),
                    buffer.image_data(),
                )
            });
            self.stream.push_buffer(buffer);
            arrivals.push(arrival);
            images.push(image);
        }
        let counters = self.counters().since(&self.counters_at_arm);
        self.last_counters = counters;
        self.last_arrivals = arrivals;
        check_arrivals(&self.last_arrivals, self.expected).map_err(|source| {
            GenicamError::Frames {
                id: self.id.clone(),
                waited_ms: start.elapsed().as_millis() as u64,
                counters,
                source,
            }
        })?;
        images
            .into_iter()
            .enumerate()
            .map(|(index, image)| {
                let (width, height, code, bytes) = image.expect("checked complete");
                let format = PixelFormat::from_pfnc(code)
                    .filter(|&f| f == self.format)
                    .ok_or_else(|| GenicamError::PixelFormat {
                        id: self.id.clone(),
                        format: format!("0x{code:08x} in frame {index}"),
                        accepted: format!("{} as configured", self.format.name()),
                    })?;
                decode(format, width.max(0) as u32, height.max(0) as u32, &bytes).map_err(
                    |source| GenicamError::Pixels {
                        id: self.id.clone(),
                        index,
                        source,
                    },
                )
            })
            .collect()
    }

    /// Ids, time stamps and statuses of the last plan's frames.
    pub fn last_arrivals(&self) -> &[Arrival] {
        &self.last_arrivals
    }

    /// The stream's counters over the last plan.
    pub fn last_counters(&self) -> StreamCounters {
        self.last_counters
    }
}

impl Drop for GenicamCamera {
    fn drop(&mut self) {
        // A camera left acquiring keeps streaming to a port nobody reads.
        let _ = self.camera.stop_acquisition();
    }
}

/// An Aravis error of camera `id` at `step`, typed.
fn device_error(id: &str, step: &str) -> impl FnOnce(aravis::glib::Error) -> GenicamError {
    let (id, step) = (id.to_owned(), step.to_owned());
    move |e| GenicamError::Device {
        id,
        step,
        message: e.message().to_owned(),
    }
}

/// Sets the camera up for triggered fringe frames: format, region, the
/// auto modes off (they would change the levels between patterns),
/// exposure and gain, continuous acquisition, frame start on the trigger.
fn configure(camera: &Camera, id: &str, settings: &GenicamSettings) -> Result<(), GenicamError> {
    let offered = camera
        .dup_available_pixel_formats_as_strings()
        .map_err(device_error(id, "read the PixelFormat entries"))?;
    let name = settings.pixel_format.name();
    if !offered.iter().any(|f| f.as_str() == name) {
        return Err(GenicamError::PixelFormat {
            id: id.into(),
            format: name.into(),
            accepted: format!(
                "the camera offers {}",
                offered
                    .iter()
                    .map(|f| f.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        });
    }
    camera
        .set_pixel_format_from_string(name)
        .map_err(device_error(id, &format!("PixelFormat = {name}")))?;
    let (x, y, width, height) = match settings.roi {
        Some((x, y, w, h)) => (x as i32, y as i32, w as i32, h as i32),
        None => {
            let (w, h) = camera
                .sensor_size()
                .map_err(device_error(id, "read SensorWidth/SensorHeight"))?;
            (0, 0, w, h)
        }
    };
    camera
        .set_region(x, y, width, height)
        .map_err(device_error(
            id,
            &format!("region {width}x{height} at ({x}, {y})"),
        ))?;
    if camera.is_exposure_auto_available().unwrap_or(false) {
        camera
            .set_exposure_time_auto(Auto::Off)
            .map_err(device_error(id, "ExposureAuto = Off"))?;
    }
    if camera.is_gain_auto_available().unwrap_or(false) {
        camera
            .set_gain_auto(Auto::Off)
            .map_err(device_error(id, "GainAuto = Off"))?;
    }
    if let Some(us) = settings.exposure_us {
        camera
            .set_exposure_time(us)
            .map_err(device_error(id, &format!("ExposureTime = {us} us")))?;
    }
    if let Some(gain) = settings.gain {
        camera
            .set_gain(gain)
            .map_err(device_error(id, &format!("Gain = {gain}")))?;
    }
    camera
        .set_acquisition_mode(AcquisitionMode::Continuous)
        .map_err(device_error(id, "AcquisitionMode = Continuous"))?;
    // FrameStart, TriggerMode On, the source; other triggers off.
    let source = &settings.trigger_source;
    camera
        .set_trigger(source)
        .map_err(device_error(id, &format!("TriggerSource = {source}")))?;
    if camera
        .is_feature_available("TriggerActivation")
        .unwrap_or(false)
    {
        let activation = &settings.trigger_activation;
        camera
            .set_string("TriggerActivation", activation)
            .map_err(device_error(
                id,
                &format!("TriggerActivation = {activation}"),
            ))?;
    }
    Ok(())
}

/// One buffer's id, stamps and status.
fn arrival_of(buffer: &Buffer) -> Arrival {
    Arrival {
        frame_id: buffer.frame_id(),
        device_ns: buffer.timestamp(),
        host_ns: buffer.system_timestamp(),
        status: match buffer.status() {
            BufferStatus::Success => ArrivalStatus::Complete,
            BufferStatus::MissingPackets => ArrivalStatus::MissingPackets,
            BufferStatus::Timeout => ArrivalStatus::TimedOut,
            BufferStatus::SizeMismatch => ArrivalStatus::SizeMismatch,
            BufferStatus::WrongPacketId => ArrivalStatus::Other("wrong packet id"),
            BufferStatus::Aborted => ArrivalStatus::Other("aborted"),
            BufferStatus::PayloadNotSupported => ArrivalStatus::Other("payload not supported"),
            _ => ArrivalStatus::Other("unknown status"),
        },
    }
}

/// Every head's camera: the hardware rig's frame source.
pub struct GenicamCameras {
    heads: Vec<GenicamCamera>,
}

impl GenicamCameras {
    /// Head `h` is `cameras[h]`.
    pub fn new(cameras: Vec<GenicamCamera>) -> Self {
        GenicamCameras { heads: cameras }
    }

    /// Head `head`'s camera.
    pub fn camera(&self, head: usize) -> Option<&GenicamCamera> {
        self.heads.get(head)
    }

    fn head_mut(&mut self, head: usize) -> Result<&mut GenicamCamera, RigError> {
        let heads = self.heads.len();
        self.heads
            .get_mut(head)
            .ok_or(RigError::NoSuchHead { head, heads })
    }
}

impl FrameSource for GenicamCameras {
    fn image_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        self.heads
            .get(head)
            .map(GenicamCamera::image_size_px)
            .ok_or(RigError::NoSuchHead {
                head,
                heads: self.heads.len(),
            })
    }

    fn arm(&mut self, frames_per_head: &[usize]) -> Result<(), RigError> {
        for (head, camera) in self.heads.iter_mut().enumerate() {
            camera.arm(frames_per_head.get(head).copied().unwrap_or(0));
        }
        Ok(())
    }

    fn take_frames(&mut self, head: usize) -> Result<Vec<Raster<f32>>, RigError> {
        self.head_mut(head)?
            .take_frames()
            .map_err(|source| RigError::Genicam { head, source })
    }

    fn take_colour_frames(&mut self, head: usize) -> Result<Vec<[Raster<f32>; 3]>, RigError> {
        let camera = self.head_mut(head)?;
        if !camera.pixel_format().is_colour() {
            return Err(RigError::NotColour { head });
        }
        camera
            .take_colour_frames()
            .map_err(|source| RigError::Genicam { head, source })
    }
}

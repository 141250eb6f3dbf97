//! `arv-fake-gv-camera-0.8` (Debian `aravis-tools`) served on 127.0.0.1 for
//! the GenICam tests and bench, killed on drop. Fake cameras all bind the
//! GVCP port 3956: one at a time.

use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::thread::sleep;
use std::time::{Duration, Instant};

use slscan::rig::genicam::aravis_camera::list_cameras;

/// Held by the running fake camera: one at a time in a process.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// A running fake GigE Vision camera and the id Aravis finds it by.
pub struct FakeGvCamera {
    child: Child,
    pub id: String,
    // Dropped after the child is killed (Drop runs before the fields).
    _port: MutexGuard<'static, ()>,
}

impl FakeGvCamera {
    /// Serves camera `serial`, losing `lost_per_thousand` GVSP packets;
    /// returns once Aravis discovers it. Waits for the fake camera before
    /// it in this process to be dropped (they share the GVCP port).
    pub fn start(serial: &str, lost_per_thousand: u32) -> FakeGvCamera {
        let port = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        let child = Command::new("arv-fake-gv-camera-0.8")
            .args(["-i", "127.0.0.1", "-s", serial])
            .args(["-r", &lost_per_thousand.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("arv-fake-gv-camera-0.8 runs (Debian: apt install aravis-tools)");
        let camera = FakeGvCamera {
            child,
            id: format!("Aravis-Fake-{serial}"),
            _port: port,
        };
        let deadline = Instant::now() + Duration::from_secs(10);
        while !list_cameras().iter().any(|c| c.id == camera.id) {
            assert!(
                Instant::now() < deadline,
                "fake camera {} not discovered",
                camera.id
            );
            sleep(Duration::from_millis(100));
        }
        camera
    }
}

impl Drop for FakeGvCamera {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

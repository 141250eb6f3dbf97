//! Serving a [`SimBoard`] on a port from a thread, and the handle that
//! stops it.
//!
//! The loop reads what the host sent (waiting a little only when there is
//! nothing to simulate), lets the board step its scan, and writes what the
//! port takes. The wall clock only paces polling; it never reaches the
//! board's virtual time.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use super::port::{BoardPort, ChannelPort, PortError};
use super::{SimBoard, SimBoardConfig};
use crate::pty::{Pty, PtyError};

/// How long the loop waits for host bytes when no scan needs simulating.
const IDLE_POLL: Duration = Duration::from_millis(5);

/// Steps of a running scan between two looks at the port, so a host's
/// `Abort` or `GetStatus` is answered promptly even during a long scan.
const STEPS_PER_TURN: usize = 64;

/// Serves `board` on `port` until `stop` is set (then `Ok`) or the port
/// fails.
pub fn serve(
    board: &Mutex<SimBoard>,
    port: &mut dyn BoardPort,
    stop: &AtomicBool,
) -> Result<(), PortError> {
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        let busy = lock(board).can_step();
        let n = port.read(&mut buf, if busy { Duration::ZERO } else { IDLE_POLL })?;
        let mut board = lock(board);
        if n > 0 {
            board.receive(&buf[..n]);
        }
        for _ in 0..STEPS_PER_TURN {
            if !board.step() {
                break;
            }
        }
        while !board.output().is_empty() {
            let (front, _) = board.output().as_slices();
            let written = port.write(front)?;
            if written == 0 {
                break;
            }
            board.consume_output(written);
        }
    }
    Ok(())
}

/// Locks the board; a panic elsewhere while holding it leaves the board
/// usable for inspection, so poisoning is ignored.
fn lock(board: &Mutex<SimBoard>) -> MutexGuard<'_, SimBoard> {
    board
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A simulated board served from its own thread.
#[derive(Debug)]
pub struct SimBoardHandle {
    path: Option<PathBuf>,
    board: Arc<Mutex<SimBoard>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), PortError>>>,
}

impl SimBoardHandle {
    /// The pty path a serial client opens (`None` for a channel board).
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The board itself (hardware logs, state). The serving thread waits
    /// while the guard is held, so hold it briefly.
    pub fn board(&self) -> MutexGuard<'_, SimBoard> {
        lock(&self.board)
    }

    /// Whether the serving thread has ended (port failure or stop).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops serving and returns how the loop ended.
    pub fn stop(mut self) -> Result<(), PortError> {
        self.shutdown()
    }

    fn shutdown(&mut self) -> Result<(), PortError> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            // The loop holds no invariant a panic could break for the
            // caller; the panic itself was already printed by the thread.
            Some(Err(_)) | None => Ok(()),
        }
    }
}

impl Drop for SimBoardHandle {
    fn drop(&mut self) {
        let _ = self.shutdown();
    }
}

fn spawn(
    board: SimBoard,
    path: Option<PathBuf>,
    mut port: impl BoardPort + Send + 'static,
) -> std::io::Result<SimBoardHandle> {
    let board = Arc::new(Mutex::new(board));
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let (board, stop) = (Arc::clone(&board), Arc::clone(&stop));
        std::thread::Builder::new()
            .name("hil-sim-board".into())
            .spawn(move || serve(&board, &mut port, &stop))?
    };
    Ok(SimBoardHandle {
        path,
        board,
        stop,
        thread: Some(thread),
    })
}

/// Opens a pseudo-terminal and serves a new simulated board on it from a
/// thread; [`SimBoardHandle::path`] is what a serial client opens. Fails if
/// no pty can be opened or the OS refuses a thread.
pub fn spawn_on_pty(config: SimBoardConfig) -> Result<SimBoardHandle, PtyError> {
    spawn_board_on_pty(SimBoard::new(config))
}

/// Serves `board`, built by the caller (e.g. [`SimBoard::with_limits`] for
/// a board with more trigger lines), on a new pseudo-terminal.
pub fn spawn_board_on_pty(board: SimBoard) -> Result<SimBoardHandle, PtyError> {
    let pty = Pty::open()?;
    let path = pty.slave_path().to_path_buf();
    Ok(spawn(board, Some(path), pty)?)
}

/// Serves a new simulated board on in-process channels: it hears the host on
/// `rx` and answers on `tx`. The thread ends when the host drops its end.
/// Fails only if the OS refuses a thread.
pub fn spawn_on_channels(
    config: SimBoardConfig,
    tx: Sender<Vec<u8>>,
    rx: Receiver<Vec<u8>>,
) -> std::io::Result<SimBoardHandle> {
    spawn(SimBoard::new(config), None, ChannelPort::new(tx, rx))
}

//! A pseudo-terminal whose slave side any serial client opens like `/dev/ttyACM0`.
//!
//! The simulated board owns the master side; the host opens the slave path
//! (`/dev/pts/N`) with the same serial code it uses for the real board. Both
//! sides are raw (no echo, no line editing, no CR/LF translation) so the
//! protocol's bytes pass through untouched.

use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// What can go wrong while creating or using the pseudo-terminal.
#[derive(Debug, thiserror::Error)]
pub enum PtyError {
    /// `openpty(3)` refused (no free ptys, no /dev/ptmx, ...).
    #[error("openpty failed")]
    Open(#[source] io::Error),
    /// The slave's termios could not be read or set to raw mode.
    #[error("could not put pty {path} in raw mode")]
    RawMode {
        /// The slave path whose terminal settings failed.
        path: PathBuf,
        /// The OS error.
        source: io::Error,
    },
    /// A file-descriptor flag (non-blocking, close-on-exec) could not be set.
    #[error("could not set flags on pty fd {fd}")]
    Flags {
        /// The descriptor concerned.
        fd: RawFd,
        /// The OS error.
        source: io::Error,
    },
    /// The slave's path could not be found with `ttyname_r(3)`.
    #[error("could not name the pty slave")]
    Name(#[source] io::Error),
    /// Reading, writing or polling the master failed.
    #[error("pty I/O failed")]
    Io(#[from] io::Error),
}

/// A raw-mode pseudo-terminal pair: the master for the simulated board, the
/// slave path for serial clients.
#[derive(Debug)]
pub struct Pty {
    master: OwnedFd,
    // Held open for the pty's life: without it the master reads EIO whenever no
    // client has the slave open, and a client that closes and reopens the path
    // (one `slscan board` run after another) would find a hung-up terminal.
    _slave: OwnedFd,
    slave_path: PathBuf,
}

impl Pty {
    /// Opens a new pseudo-terminal in raw mode with a non-blocking master.
    pub fn open() -> Result<Self, PtyError> {
        let mut master: libc::c_int = -1;
        let mut slave: libc::c_int = -1;
        // SAFETY: both out-pointers are valid; name, termios and winsize are
        // optional (null) per openpty(3).
        let rc = unsafe {
            libc::openpty(
                &mut master,
                &mut slave,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        };
        if rc != 0 {
            return Err(PtyError::Open(io::Error::last_os_error()));
        }
        // SAFETY: openpty succeeded, so both descriptors are open and ours alone.
        let master = unsafe { OwnedFd::from_raw_fd(master) };
        let slave = unsafe { OwnedFd::from_raw_fd(slave) };
        set_cloexec(master.as_raw_fd())?;
        set_cloexec(slave.as_raw_fd())?;
        set_nonblocking(master.as_raw_fd())?;
        let slave_path = tty_name(slave.as_raw_fd())?;
        set_raw(slave.as_raw_fd()).map_err(|source| PtyError::RawMode {
            path: slave_path.clone(),
            source,
        })?;
        Ok(Self {
            master,
            _slave: slave,
            slave_path,
        })
    }

    /// The path a serial client opens, such as `/dev/pts/7`.
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }

    /// Waits up to `timeout` for bytes from the client and reads what is there;
    /// `Ok(0)` means nothing arrived in time.
    pub fn read(&self, buf: &mut [u8], timeout: Duration) -> Result<usize, PtyError> {
        if !poll(self.master.as_raw_fd(), libc::POLLIN, timeout)? {
            return Ok(0);
        }
        // SAFETY: buf is valid for buf.len() bytes for the duration of the call.
        let n = unsafe { libc::read(self.master.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
        match n {
            n if n >= 0 => Ok(n as usize),
            _ => would_block_is_zero(io::Error::last_os_error()),
        }
    }

    /// Writes as many bytes as the terminal takes now; `Ok(0)` when its buffer
    /// is full (the client is not reading).
    pub fn write(&self, bytes: &[u8]) -> Result<usize, PtyError> {
        // SAFETY: bytes is valid for bytes.len() bytes for the duration of the call.
        let n = unsafe { libc::write(self.master.as_raw_fd(), bytes.as_ptr().cast(), bytes.len()) };
        match n {
            n if n >= 0 => Ok(n as usize),
            _ => would_block_is_zero(io::Error::last_os_error()),
        }
    }

    /// Waits up to `timeout` until the terminal takes more bytes.
    pub fn wait_writable(&self, timeout: Duration) -> Result<bool, PtyError> {
        poll(self.master.as_raw_fd(), libc::POLLOUT, timeout)
    }
}

fn would_block_is_zero(err: io::Error) -> Result<usize, PtyError> {
    match err.kind() {
        io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted => Ok(0),
        _ => Err(PtyError::Io(err)),
    }
}

/// `poll(2)` one descriptor for `events`; true when one of them is ready.
fn poll(fd: RawFd, events: libc::c_short, timeout: Duration) -> Result<bool, PtyError> {
    let mut pfd = libc::pollfd {
        fd,
        events,
        revents: 0,
    };
    let timeout_ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
    // SAFETY: one valid pollfd.
    let rc = unsafe { libc::poll(&mut pfd, 1, timeout_ms) };
    if rc < 0 {
        let err = io::Error::last_os_error();
        return match err.kind() {
            io::ErrorKind::Interrupted => Ok(false),
            _ => Err(PtyError::Io(err)),
        };
    }
    Ok(rc > 0 && pfd.revents & events != 0)
}

fn set_cloexec(fd: RawFd) -> Result<(), PtyError> {
    // SAFETY: fcntl on a descriptor we own.
    let rc = unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) };
    if rc < 0 {
        return Err(PtyError::Flags {
            fd,
            source: io::Error::last_os_error(),
        });
    }
    Ok(())
}

fn set_nonblocking(fd: RawFd) -> Result<(), PtyError> {
    // SAFETY: fcntl on a descriptor we own.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    // SAFETY: as above.
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) } < 0 {
        return Err(PtyError::Flags {
            fd,
            source: io::Error::last_os_error(),
        });
    }
    Ok(())
}

/// Raw mode on the slave, so nothing echoes bytes back before a client has
/// opened the port and set raw mode itself.
fn set_raw(fd: RawFd) -> io::Result<()> {
    let mut termios = std::mem::MaybeUninit::<libc::termios>::uninit();
    // SAFETY: tcgetattr fills the struct when it returns 0.
    if unsafe { libc::tcgetattr(fd, termios.as_mut_ptr()) } != 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: initialised by the successful tcgetattr above.
    let mut termios = unsafe { termios.assume_init() };
    // SAFETY: cfmakeraw only edits the struct.
    unsafe { libc::cfmakeraw(&mut termios) };
    // SAFETY: valid descriptor and struct.
    if unsafe { libc::tcsetattr(fd, libc::TCSANOW, &termios) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

fn tty_name(fd: RawFd) -> Result<PathBuf, PtyError> {
    let mut buf = [0u8; 128];
    // SAFETY: buf is valid for its length; ttyname_r NUL-terminates on success.
    let rc = unsafe { libc::ttyname_r(fd, buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return Err(PtyError::Name(io::Error::from_raw_os_error(rc)));
    }
    let len = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let name = std::str::from_utf8(&buf[..len])
        .map_err(|e| PtyError::Name(io::Error::new(io::ErrorKind::InvalidData, e)))?;
    Ok(PathBuf::from(name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs::OpenOptions;
    use std::io::{Read, Write};

    const WAIT: Duration = Duration::from_secs(5);

    #[test]
    fn slave_path_is_a_pts_device() {
        let pty = Pty::open().unwrap();
        assert!(
            pty.slave_path().starts_with("/dev/pts/"),
            "{:?}",
            pty.slave_path()
        );
    }

    #[test]
    fn bytes_pass_both_ways_untouched() {
        let pty = Pty::open().unwrap();
        let mut client = OpenOptions::new()
            .read(true)
            .write(true)
            .open(pty.slave_path())
            .unwrap();
        // Bytes a cooked terminal would alter: NUL, CR, LF, ^C, ^D, DEL.
        let sent: Vec<u8> = vec![0x00, b'\r', b'\n', 0x03, 0x04, 0x7f, 0xff, 0x11, 0x13];
        client.write_all(&sent).unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        while got.len() < sent.len() {
            let n = pty.read(&mut buf, WAIT).unwrap();
            assert!(n > 0, "timed out after {got:?}");
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, sent);

        assert_eq!(pty.write(&sent).unwrap(), sent.len());
        let mut back = vec![0u8; sent.len()];
        client.read_exact(&mut back).unwrap();
        assert_eq!(back, sent);
    }

    #[test]
    fn read_times_out_with_zero_when_nobody_writes() {
        let pty = Pty::open().unwrap();
        let mut buf = [0u8; 8];
        assert_eq!(pty.read(&mut buf, Duration::from_millis(1)).unwrap(), 0);
    }

    #[test]
    fn survives_a_client_closing_and_another_opening() {
        let pty = Pty::open().unwrap();
        for round in 0u8..2 {
            let mut client = OpenOptions::new()
                .read(true)
                .write(true)
                .open(pty.slave_path())
                .unwrap();
            client.write_all(&[round]).unwrap();
            let mut buf = [0u8; 8];
            assert_eq!(pty.read(&mut buf, WAIT).unwrap(), 1);
            assert_eq!(buf[0], round);
        }
        let mut buf = [0u8; 8];
        assert_eq!(pty.read(&mut buf, Duration::from_millis(1)).unwrap(), 0);
    }
}

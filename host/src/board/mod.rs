//! The sync board client: typed requests over a serial port (the real board
//! or hil-sim's pseudo-terminal) or in-process channels.
//!
//! ```text
//! BoardClient --HostFrame{id, Request}--> Transport (serial | channel) --> board
//!      ^                                                                    |
//!      +-- Response{id} / Event / LinkError <-- FrameAccumulator <----------+
//! ```
//!
//! - [`client`]: one method per request, ids, timeouts and retries.
//! - [`session`]: whole jobs: upload a plan in chunks, run it, collect events.
//! - [`transport`]: the byte links.
//! - [`plan_file`]: plans as JSON files.
//! - [`error`]: link failures apart from board refusals.

pub mod client;
pub mod error;
pub mod plan_file;
pub mod session;
#[cfg(test)]
mod test_board;
pub mod transport;

pub use client::{BoardClient, ClientConfig, LinkStats};
pub use error::{BoardError, LinkError};
pub use session::ScanOutcome;
pub use transport::{ChannelTransport, SerialTransport, Transport};

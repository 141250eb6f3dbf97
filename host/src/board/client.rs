//! The typed board client: one method per request, over any [`Transport`].
//!
//! Each request gets a fresh id; a retry (after a timeout, or at once when
//! the board reports an unreadable frame) re-sends the same frame with the
//! same id, so whichever copy the board answers pairs with the question, and
//! the board answers a repeated id from its cache instead of running it twice. Events that arrive while a request waits are queued for
//! [`BoardClient::next_event`]. Timeouts are the only thing measured with the
//! host's clock; scan timing comes from the board's own ticks.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use protocol::limits::MAX_FRAME_BYTES;
use protocol::{
    decode_payload, encode_frame, BoardFrame, BoardLimits, BoardStatus, DeviceInfo, Event,
    Exposure, FrameAccumulator, FrameError, HostFrame, PlanHeader, PlanSummary, Request, RequestId,
    Response, ScanReport, WireError, PROTOCOL_VERSION,
};

use super::error::{BoardError, LinkError};
use super::transport::Transport;

/// Turns an [`Answer`] into the wanted payload, or an `UnexpectedResponse`
/// naming the request.
macro_rules! expect {
    ($call:expr, $pattern:pat => $value:expr) => {{
        let answer = $call?;
        match answer.response {
            $pattern => Ok($value),
            other => Err(BoardError::UnexpectedResponse {
                request: answer.request,
                id: answer.id,
                response: Box::new(other),
            }),
        }
    }};
}

/// A response paired with the request it answers.
struct Answer {
    request: &'static str,
    id: RequestId,
    response: Response,
}

/// Timeouts and retries of the client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClientConfig {
    /// How long one attempt waits for its answer.
    pub attempt_timeout: Duration,
    /// Attempts per request (1 = no retry).
    pub attempts: u32,
}

impl Default for ClientConfig {
    /// 500 ms per attempt, 3 attempts: a vanished board is reported within
    /// about 1.5 s, while a USB hiccup is retried.
    fn default() -> Self {
        Self {
            attempt_timeout: Duration::from_millis(500),
            attempts: 3,
        }
    }
}

/// Counters of what the link went through.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Requests sent (not counting retries).
    pub requests: u64,
    /// Extra attempts (after a timeout, or the board saying it could not
    /// read a frame).
    pub retries: u64,
    /// Frames from the board that failed COBS, CRC or decoding.
    pub corrupt_frames: u64,
    /// `LinkError` frames: the board could not read something we sent.
    pub board_link_errors: u64,
    /// The last of those complaints.
    pub last_board_link_error: Option<WireError>,
    /// Answers to requests no longer waited for (late duplicates).
    pub stale_responses: u64,
}

/// A client of the sync board's protocol.
#[derive(Debug)]
pub struct BoardClient<T: Transport> {
    transport: T,
    config: ClientConfig,
    rx: FrameAccumulator,
    next_id: RequestId,
    events: VecDeque<Event>,
    stats: LinkStats,
    // What the board said it can do in its last `Hello` / `GetInfo` answer:
    // `upload_plan` checks a plan's heads against it before sending.
    limits: Option<BoardLimits>,
}

impl<T: Transport> BoardClient<T> {
    /// A client over `transport`; no bytes are exchanged yet.
    pub fn new(transport: T, config: ClientConfig) -> Self {
        Self {
            transport,
            config,
            rx: FrameAccumulator::new(),
            next_id: 1,
            events: VecDeque::new(),
            stats: LinkStats::default(),
            limits: None,
        }
    }

    /// A client that has completed the handshake, with the board's info.
    pub fn connect(transport: T, config: ClientConfig) -> Result<(Self, DeviceInfo), BoardError> {
        let mut client = Self::new(transport, config);
        let info = client.hello()?;
        Ok((client, info))
    }

    /// The limits the board reported in its last `Hello` or `GetInfo`
    /// answer; `None` before either.
    pub fn board_limits(&self) -> Option<BoardLimits> {
        self.limits
    }

    /// The link counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The client's timeouts and retries.
    pub fn config(&self) -> ClientConfig {
        self.config
    }

    /// Changes timeouts and retries.
    pub fn set_config(&mut self, config: ClientConfig) {
        self.config = config;
    }

    /// The transport, e.g. to inject raw bytes in a test.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// Handshake: checks the protocol versions match.
    pub fn hello(&mut self) -> Result<DeviceInfo, BoardError> {
        let request = Request::Hello {
            protocol_version: PROTOCOL_VERSION,
        };
        let info: DeviceInfo = expect!(self.call(request), Response::Hello(info) => info)?;
        self.limits = Some(info.limits);
        Ok(info)
    }

    /// The board's info.
    pub fn info(&mut self) -> Result<DeviceInfo, BoardError> {
        let info: DeviceInfo = expect!(self.call(Request::GetInfo), Response::Info(info) => info)?;
        self.limits = Some(info.limits);
        Ok(info)
    }

    /// Starts a plan upload.
    pub fn begin_plan(&mut self, header: &PlanHeader) -> Result<(), BoardError> {
        expect!(self.call(Request::BeginPlan(header.clone())), Response::PlanBegun => ())
    }

    /// Uploads exposure `index` of the plan being sent.
    pub fn add_exposure(&mut self, index: u16, exposure: &Exposure) -> Result<(), BoardError> {
        let request = Request::AddExposure {
            index,
            exposure: exposure.clone(),
        };
        expect!(self.call(request), Response::ExposureAdded { .. } => ())
    }

    /// Validates and compiles the uploaded plan on the board.
    pub fn commit_plan(&mut self) -> Result<PlanSummary, BoardError> {
        expect!(self.call(Request::CommitPlan), Response::PlanCommitted(summary) => summary)
    }

    /// Loads the compiled plan into the board's timers.
    pub fn arm(&mut self) -> Result<(), BoardError> {
        expect!(self.call(Request::Arm), Response::Armed => ())
    }

    /// Starts the armed scan `delay_ns` after the board receives the request;
    /// returns the board tick of the first cycle's start.
    pub fn start(&mut self, delay_ns: u32) -> Result<u64, BoardError> {
        expect!(self.call(Request::Start { delay_ns }), Response::Started { start_tick } => start_tick)
    }

    /// Stops any scan now; returns its counters.
    pub fn abort(&mut self) -> Result<ScanReport, BoardError> {
        expect!(self.call(Request::Abort), Response::Aborted(report) => report)
    }

    /// The sequencer's state, the board's clock and counters.
    pub fn status(&mut self) -> Result<BoardStatus, BoardError> {
        expect!(self.call(Request::GetStatus), Response::Status(status) => status)
    }

    /// Liveness check; the board echoes `nonce`.
    pub fn ping(&mut self, nonce: u32) -> Result<(), BoardError> {
        let answer = self.call(Request::Ping { nonce })?;
        match answer.response {
            Response::Pong { nonce: echoed } if echoed == nonce => Ok(()),
            other => Err(BoardError::UnexpectedResponse {
                request: answer.request,
                id: answer.id,
                response: Box::new(other),
            }),
        }
    }

    /// The next event from the board, waiting up to `timeout`; `Ok(None)` if
    /// none came.
    pub fn next_event(&mut self, timeout: Duration) -> Result<Option<Event>, BoardError> {
        if let Some(event) = self.events.pop_front() {
            return Ok(Some(event));
        }
        let deadline = Instant::now() + timeout;
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            for item in self.read_frames(deadline - now)? {
                match item {
                    Ok(BoardFrame::Event(event)) => self.events.push_back(event),
                    Ok(BoardFrame::Response { .. }) => self.stats.stale_responses += 1,
                    Ok(BoardFrame::LinkError(error)) => self.note_link_error(error),
                    Err(_) => self.stats.corrupt_frames += 1,
                }
            }
            if let Some(event) = self.events.pop_front() {
                return Ok(Some(event));
            }
        }
    }

    /// Sends `request` and waits for its answer, retrying with the same id; a
    /// `Refused` answer becomes [`BoardError::Refused`].
    fn call(&mut self, request: Request) -> Result<Answer, BoardError> {
        let name = request_name(&request);
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1).max(1);
        self.stats.requests += 1;
        // A leading delimiter ends whatever half frame the board may hold (a
        // truncated earlier frame), so this one is read on its own.
        let mut frame = [0u8; MAX_FRAME_BYTES + 1];
        let len = encode_frame(&HostFrame { id, request }, &mut frame[1..]).map_err(|error| {
            LinkError::Encode {
                request: name,
                error,
            }
        })?;
        let frame = &frame[..len + 1];
        let started = Instant::now();
        let mut corrupt_frames = 0u32;
        let mut unreadable = None;
        for attempt in 1..=self.config.attempts.max(1) {
            if attempt > 1 {
                self.stats.retries += 1;
            }
            self.transport.send(frame)?;
            let deadline = Instant::now() + self.config.attempt_timeout;
            // The board answers every frame it reads, and a retry of an id it
            // already answered gets that same answer again (board-core keeps
            // the last one), so when the board says it could not read a frame
            // the client re-sends at once instead of waiting out the attempt:
            // if the complaint was about other bytes, the copy costs nothing.
            unreadable = None;
            while let Some(left) = deadline.checked_duration_since(Instant::now()) {
                if left.is_zero() || unreadable.is_some() {
                    break;
                }
                let mut answer = None;
                for item in self.read_frames(left)? {
                    match item {
                        Ok(BoardFrame::Response { id: got, response }) if got == id => {
                            answer.get_or_insert(response);
                        }
                        Ok(BoardFrame::Response { .. }) => self.stats.stale_responses += 1,
                        Ok(BoardFrame::Event(event)) => self.events.push_back(event),
                        Ok(BoardFrame::LinkError(error)) => {
                            self.note_link_error(error);
                            unreadable = Some(error);
                        }
                        Err(_) => {
                            self.stats.corrupt_frames += 1;
                            corrupt_frames += 1;
                        }
                    }
                }
                match answer {
                    Some(Response::Refused(error)) => {
                        return Err(BoardError::Refused {
                            request: name,
                            id,
                            error,
                        })
                    }
                    Some(response) => {
                        return Ok(Answer {
                            request: name,
                            id,
                            response,
                        })
                    }
                    None => {}
                }
            }
        }
        let attempts = self.config.attempts.max(1);
        Err(match unreadable {
            Some(error) => LinkError::Unreadable {
                request: name,
                id,
                attempts,
                error,
            },
            None => LinkError::Timeout {
                request: name,
                id,
                attempts,
                waited_ms: started.elapsed().as_millis() as u64,
                corrupt_frames,
            },
        }
        .into())
    }

    fn note_link_error(&mut self, error: WireError) {
        self.stats.board_link_errors += 1;
        self.stats.last_board_link_error = Some(error);
    }

    /// Reads what arrives within `timeout` and decodes the frames it completes.
    fn read_frames(
        &mut self,
        timeout: Duration,
    ) -> Result<Vec<Result<BoardFrame, FrameError>>, LinkError> {
        let mut buf = [0u8; 1024];
        let n = self.transport.recv(&mut buf, timeout)?;
        let mut frames = Vec::new();
        self.rx.feed(&buf[..n], |frame| {
            frames.push(frame.and_then(decode_payload::<BoardFrame>));
        });
        Ok(frames)
    }
}

/// The request's name, for errors.
pub fn request_name(request: &Request) -> &'static str {
    match request {
        Request::Hello { .. } => "Hello",
        Request::GetInfo => "GetInfo",
        Request::BeginPlan(_) => "BeginPlan",
        Request::AddExposure { .. } => "AddExposure",
        Request::CommitPlan => "CommitPlan",
        Request::Arm => "Arm",
        Request::Start { .. } => "Start",
        Request::Abort => "Abort",
        Request::GetStatus => "GetStatus",
        Request::Ping { .. } => "Ping",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::test_board::{answer, finish, frame, info, scripted_board, SHORT};
    use crate::board::transport::ChannelTransport;

    #[test]
    fn handshake_returns_the_board_info() {
        let (mut client, board) = scripted_board(|_, f| match f.request {
            Request::Hello { protocol_version } if protocol_version == PROTOCOL_VERSION => {
                vec![answer(f.id, Response::Hello(info()))]
            }
            _ => vec![answer(f.id, Response::Refused(WireError::NoPlan))],
        });
        assert_eq!(client.hello().unwrap(), info());
        assert_eq!(finish(client, board).len(), 1);
    }

    #[test]
    fn retry_reuses_the_request_id() {
        // The board ignores the first copy and answers the second.
        let (mut client, board) = scripted_board(|n, f| match n {
            0 => vec![],
            _ => vec![answer(f.id, Response::Pong { nonce: 5 })],
        });
        client.ping(5).unwrap();
        assert_eq!(client.stats().retries, 1);
        let seen = finish(client, board);
        assert_eq!(seen.len(), 2);
        assert_eq!(seen[0], seen[1], "the retry is the very same frame");
    }

    #[test]
    fn ids_differ_between_requests() {
        let (mut client, board) =
            scripted_board(|_, f| vec![answer(f.id, Response::Pong { nonce: 1 })]);
        client.ping(1).unwrap();
        client.ping(1).unwrap();
        let seen = finish(client, board);
        assert_ne!(seen[0].id, seen[1].id);
    }

    #[test]
    fn silent_board_is_a_timeout_after_all_attempts() {
        let (mut client, board) = scripted_board(|_, _| vec![]);
        let err = client.status().unwrap_err();
        match &err {
            BoardError::Link(LinkError::Timeout {
                request,
                attempts,
                waited_ms,
                ..
            }) => {
                assert_eq!(*request, "GetStatus");
                assert_eq!(*attempts, 3);
                assert!(*waited_ms >= 300, "{waited_ms}");
            }
            other => panic!("expected a timeout, got {other}"),
        }
        assert!(err.is_link_failure());
        assert_eq!(finish(client, board).len(), 3);
    }

    #[test]
    fn refusal_is_not_a_link_failure_and_carries_the_reason() {
        let (mut client, board) =
            scripted_board(|_, f| vec![answer(f.id, Response::Refused(WireError::NoPlan))]);
        let err = client.arm().unwrap_err();
        assert!(!err.is_link_failure());
        assert!(
            matches!(
                err,
                BoardError::Refused {
                    request: "Arm",
                    error: WireError::NoPlan,
                    ..
                }
            ),
            "{err:?}"
        );
        finish(client, board);
    }

    #[test]
    fn wrong_kind_of_answer_is_unexpected_response() {
        let (mut client, board) = scripted_board(|_, f| vec![answer(f.id, Response::Armed)]);
        let err = client.commit_plan().unwrap_err();
        assert!(
            matches!(
                err,
                BoardError::UnexpectedResponse {
                    request: "CommitPlan",
                    ..
                }
            ),
            "{err:?}"
        );
        finish(client, board);
    }

    #[test]
    fn garbage_stale_answers_and_events_around_the_answer_are_sorted_out() {
        let event = Event::StateChanged {
            state: protocol::ScanState::Armed,
            tick: 9,
        };
        let (mut client, board) = scripted_board(move |_, f| {
            let mut corrupt = answer(f.id, Response::Pong { nonce: 3 });
            corrupt[2] ^= 0x10;
            vec![
                corrupt,
                answer(f.id.wrapping_add(100), Response::Armed),
                frame(&BoardFrame::Event(event)),
                answer(f.id, Response::Pong { nonce: 3 }),
                frame(&BoardFrame::LinkError(WireError::Frame(FrameError::Cobs))),
            ]
        });
        client.ping(3).unwrap();
        let stats = client.stats();
        assert_eq!(stats.corrupt_frames, 1);
        assert_eq!(stats.stale_responses, 1);
        assert_eq!(stats.retries, 0);
        assert_eq!(client.next_event(Duration::ZERO).unwrap(), Some(event));
        // The complaint after the answer is read while waiting for events.
        assert_eq!(client.next_event(Duration::from_millis(50)).unwrap(), None);
        assert_eq!(client.stats().board_link_errors, 1);
        finish(client, board);
    }

    #[test]
    fn unreadable_frame_is_resent_at_once() {
        // The first copy "arrives garbled"; the second is answered. With a
        // long attempt timeout, only an immediate re-send finishes quickly.
        let (mut client, board) = scripted_board(|n, f| match n {
            0 => vec![frame(&BoardFrame::LinkError(WireError::Frame(
                FrameError::Cobs,
            )))],
            _ => vec![answer(f.id, Response::Pong { nonce: 4 })],
        });
        client.set_config(ClientConfig {
            attempt_timeout: Duration::from_secs(60),
            attempts: 2,
        });
        let asked = Instant::now();
        client.ping(4).unwrap();
        assert!(asked.elapsed() < Duration::from_secs(30));
        assert_eq!(client.stats().retries, 1);
        finish(client, board);
    }

    #[test]
    fn board_that_cannot_read_us_is_reported_as_unreadable() {
        let (mut client, board) = scripted_board(|_, _| {
            vec![frame(&BoardFrame::LinkError(WireError::Frame(
                FrameError::Cobs,
            )))]
        });
        let err = client.info().unwrap_err();
        assert!(
            matches!(
                err,
                BoardError::Link(LinkError::Unreadable {
                    request: "GetInfo",
                    attempts: 3,
                    ..
                })
            ),
            "{err:?}"
        );
        finish(client, board);
    }

    #[test]
    fn vanished_peer_is_port_gone_not_a_hang() {
        let (host, board) = ChannelTransport::pair();
        drop(board);
        let mut client = BoardClient::new(host, SHORT);
        let err = client.ping(1).unwrap_err();
        assert!(
            matches!(err, BoardError::Link(LinkError::PortGone { .. })),
            "{err:?}"
        );
    }
}

//! `hil-sim serve` as a user runs it: it prints a pty path on stdout, and a
//! plain file opened on that path speaks the board's protocol.

use std::fs::OpenOptions;
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use protocol::limits::MAX_FRAME_BYTES;
use protocol::{
    decode_payload, encode_frame, BoardFrame, FrameAccumulator, HostFrame, Request, Response,
    PROTOCOL_VERSION,
};

#[test]
fn serve_prints_a_pty_that_answers_hello() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(["serve", "--seed", "3"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("hil-sim starts");
    let mut path = String::new();
    let stdout = child.stdout.take().expect("piped stdout");
    BufReader::new(stdout).read_line(&mut path).expect("a line");
    let path = path.trim().to_owned();
    assert!(path.starts_with("/dev/pts/"), "{path:?}");

    let mut port = OpenOptions::new()
        .read(true)
        .write(true)
        .open(&path)
        .expect("the pty opens like a serial port");
    let mut frame = [0u8; MAX_FRAME_BYTES];
    let hello = HostFrame {
        id: 42,
        request: Request::Hello {
            protocol_version: PROTOCOL_VERSION,
        },
    };
    let n = encode_frame(&hello, &mut frame).expect("encode");
    port.write_all(&frame[..n]).expect("write");

    // Read on a thread so a silent board fails the test instead of hanging it.
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut acc = FrameAccumulator::new();
        let mut buf = [0u8; 256];
        loop {
            let Ok(n) = port.read(&mut buf) else { return };
            let mut answers = Vec::new();
            acc.feed(&buf[..n], |f| {
                answers.push(f.and_then(decode_payload::<BoardFrame>))
            });
            if let Some(answer) = answers.pop() {
                let _ = tx.send(answer);
                return;
            }
        }
    });
    let answer = rx.recv_timeout(Duration::from_secs(10));
    child.kill().expect("stop hil-sim");
    child.wait().expect("reap hil-sim");
    match answer {
        Ok(Ok(BoardFrame::Response {
            id: 42,
            response: Response::Hello(info),
        })) => assert_eq!(info.protocol_version, PROTOCOL_VERSION),
        other => panic!("expected the Hello answer, got {other:?}"),
    }
}

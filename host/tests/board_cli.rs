//! `slscan board` as a user runs it: the binary against a simulated board it
//! starts itself (`--sim`) and against a pty served by another thread
//! (`--port`), plus the errors a user sees for bad input.

use std::path::PathBuf;
use std::process::{Command, Output};

fn slscan(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slscan"))
        .args(args)
        .output()
        .expect("slscan runs")
}

fn plan(name: &str) -> String {
    let path: PathBuf = [env!("CARGO_MANIFEST_DIR"), "examples", "plans", name]
        .iter()
        .collect();
    path.to_string_lossy().into_owned()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn info_against_a_simulated_board() {
    let out = slscan(&["board", "info", "--sim"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("timer clock     170 MHz"), "{stdout}");
    assert!(stdout.contains("reset cause     Simulated"), "{stdout}");
    assert!(text(&out.stderr).contains("simulated board on /dev/pts/"));
}

#[test]
fn run_plan_streams_events_and_reports_the_board_counters() {
    let out = slscan(&[
        "board",
        "run-plan",
        &plan("multiplexed_24_at_5khz.json"),
        "--sim",
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}\n{stdout}", text(&out.stderr));
    assert!(stdout.contains("state -> Running"), "{stdout}");
    assert!(stdout.contains("ended           Done"), "{stdout}");
    assert!(
        stdout.contains("150 expected, 150 on time, 0 late, 0 missing, 0 unexpected"),
        "{stdout}"
    );
}

#[test]
fn run_plan_over_a_port_path_like_a_real_board() {
    let board =
        hil_sim::board::spawn_on_pty(hil_sim::board::SimBoardConfig::default()).expect("pty board");
    let port = board
        .path()
        .expect("pty path")
        .to_string_lossy()
        .into_owned();
    let out = slscan(&[
        "board",
        "run-plan",
        &plan("flood_preliminaries.json"),
        "--port",
        &port,
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("ended           Done"));
    assert_eq!(board.board().hardware().recorded().len(), 7 * 2 * 2);
}

#[test]
fn missing_port_is_a_clear_error_naming_it() {
    let out = slscan(&["board", "info", "--port", "/dev/ttyACM-not-there"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("/dev/ttyACM-not-there"), "{stderr}");
}

#[test]
fn bad_plan_file_is_a_clear_error_and_nothing_runs() {
    let dir = std::env::temp_dir().join(format!("slscan-board-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let bad = dir.join("bad.json");
    std::fs::write(&bad, "{ \"heads\": 3 }").expect("write");
    let out = slscan(&["board", "run-plan", &bad.to_string_lossy(), "--sim"]);
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(out.status.code(), Some(1));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("bad.json") && stderr.contains("not a valid plan"),
        "{stderr}"
    );
}

#[test]
fn port_or_sim_is_required() {
    let out = slscan(&["board", "info"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("--port"));
}

#[test]
fn abort_leaves_the_board_idle_or_aborted() {
    let out = slscan(&["board", "abort", "--sim"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // A fresh board has nothing to abort: it stays Idle.
    assert!(
        text(&out.stdout).contains("state           Idle"),
        "{}",
        text(&out.stdout)
    );
}

#[test]
fn abort_stops_a_scan_another_session_left_armed() {
    use slscan::board::{BoardClient, ClientConfig, SerialTransport};
    let board =
        hil_sim::board::spawn_on_pty(hil_sim::board::SimBoardConfig::default()).expect("pty board");
    let path = board.path().expect("pty path").to_path_buf();
    {
        let transport = SerialTransport::open(&path, 115_200).expect("open");
        let (mut client, _) =
            BoardClient::connect(transport, ClientConfig::default()).expect("hello");
        client
            .upload_plan(&protocol::plan::examples::dual_head_psp(1))
            .expect("upload");
        client.arm().expect("arm");
    }
    let out = slscan(&["board", "abort", "--port", &path.to_string_lossy()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("state           Aborted"),
        "{}",
        text(&out.stdout)
    );
}

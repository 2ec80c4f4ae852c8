//! Running the tool as a user would, for the tests of careless and hostile use: a time limit on every
//! run (a hang is a defect too), shell scripts for ulimits and redirections, and the checks of a refusal.

use std::fs;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

pub const BIN: &str = env!("CARGO_BIN_EXE_ogm-corners");

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs `cmd`, killing it and failing the test if it takes longer than `secs` (a hang is a defect too).
/// Its output is read while it runs, so a full pipe never blocks it.
pub fn within(mut cmd: Command, secs: u64) -> Output {
    let child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(child.wait_with_output().unwrap()));
    match rx.recv_timeout(Duration::from_secs(secs)) {
        Ok(o) => o,
        Err(_) => {
            let _ = Command::new("kill")
                .args(["-KILL", &pid.to_string()])
                .status();
            let o = rx.recv().unwrap();
            panic!("still running after {secs} s; stderr: {}", stderr(&o));
        }
    }
}

/// Asserts that the run was refused as bad input (exit 2) with `needle` in its error.
#[track_caller]
pub fn refused(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains(needle), "expected {needle:?} in: {e}");
    assert!(
        e.starts_with("ogm-corners: error: ") || e.contains("\nogm-corners: error: "),
        "{e}"
    );
}

pub fn signal(pid: u32, sig: rustix::process::Signal) {
    let pid = rustix::process::Pid::from_raw(pid as i32).expect("a child's pid is positive");
    let _ = rustix::process::kill_process(pid, sig);
}

pub fn ogm(args: &[&str]) -> Output {
    let mut c = Command::new(BIN);
    c.args(args);
    within(c, 120)
}

/// Runs a shell script with `$OGM` set to the tool (for ulimit, traps and redirections).
pub fn sh(script: &str) -> Output {
    let mut c = Command::new("sh");
    c.arg("-c").arg(script).env("OGM", BIN);
    within(c, 120)
}

pub fn tmp() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("ogm-reliability-")
        .tempdir()
        .unwrap()
}

/// Files in `dir`, sorted (hidden temporary files included).
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Whether the tests run as root (who may write into read-only folders).
pub fn is_root() -> bool {
    let o = Command::new("id").arg("-u").output().unwrap();
    String::from_utf8_lossy(&o.stdout).trim() == "0"
}

/// Runs the tool with `args`, asserts that it succeeded, and parses its standard output as JSON.
#[track_caller]
pub fn ogm_json(args: &[&str]) -> serde_json::Value {
    let o = ogm(args);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&stdout(&o)).unwrap()
}

//! The binary as a process: a closed stderr, signals in the middle of a run, output to
//! a pipe.

use std::process::Command;

use crate::common::cli::{command, texsyn, text, GRAVEL};
use crate::common::TempDir;

/// A reader that goes away (`texsyn ... 2>&1 | head -1`) loses the messages, not the
/// work: before, the next progress line panicked ("failed printing to stderr", exit 101).
#[test]
fn a_closed_stderr_does_not_stop_the_run() {
    use std::process::Stdio;
    let dir = TempDir::new("closed-stderr");
    // The pipe's read end is closed before the child writes anything.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let status = command(dir.root())
        .args(["analyze", GRAVEL, "-o", "a.tsa"])
        .stdout(Stdio::null())
        .stderr(writer)
        .status()
        .unwrap();
    assert_eq!(status.code(), Some(0));
    assert!(dir.path("a.tsa").is_file());
}

/// Ctrl-C or `kill` in the middle of an `advect` run into a frame folder: the process
/// exits with 128 + the signal and its staging folder (`.NAME.partial-PID`, there from
/// the start of the run) is removed; an existing output is left as it was.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_run_removes_its_unfinished_outputs() {
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let dir = TempDir::new("interrupt");
        std::fs::write(dir.path("keep.txt"), b"x").unwrap();
        let mut child = command(dir.root())
            .args([
                "advect", GRAVEL, "-o", "frames", "--flow", "vortex", "--size", "64", "--frames",
                "100000", "-q",
            ])
            .spawn()
            .unwrap();
        // Wait for the staging folder (at most 60 s on a slow machine).
        let start = std::time::Instant::now();
        while !dir
            .files()
            .iter()
            .any(|f| f.starts_with(".frames.partial-"))
        {
            if let Some(status) = child.try_wait().unwrap() {
                panic!("advect ended before it was interrupted: {status:?}");
            }
            assert!(
                start.elapsed().as_secs() < 60,
                "no staging folder appeared: {:?}",
                dir.files()
            );
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let killed = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{signal}: {status:?}");
        assert_eq!(dir.files(), vec!["keep.txt".to_string()], "SIG{signal}");
    }
}

/// `-o /dev/stdout` (or `-o -`) into a pipe: the link leads to a stream, which is written
/// through (it used to be followed to `pipe:[..]` and fail to create a temporary file
/// there; `-` made a file named `-`).
#[cfg(target_os = "linux")]
#[test]
fn output_to_dev_stdout_in_a_pipe() {
    let dir = TempDir::new("stdout");
    for target in ["/dev/stdout", "-"] {
        let out = texsyn(&dir, &["synth", GRAVEL, "-o", target, "--size", "32", "-q"]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        assert!(
            out.stdout.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{:?}",
            &out.stdout[..8.min(out.stdout.len())]
        );
        assert!(dir.files().is_empty(), "{:?}", dir.files());
    }
}

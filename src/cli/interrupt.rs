//! Ctrl-C and `kill`: remove the outputs in progress before exiting.
//!
//! Outputs are written to temporary files (and `advect` frames to a staging folder) and
//! renamed into place when complete; destructors remove them after errors, but a signal
//! ends the process without running any. So SIGINT, SIGTERM and SIGHUP are blocked in
//! every thread (set before any thread starts, the mask is inherited, the GPU driver's
//! threads included) and taken by one thread that waits for them, removes this process's
//! temporary files and staging folder of every output listed with [`register_output`]
//! and exits with 128 + the signal number, as a shell reports a process killed by it.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The outputs this run writes (files, or `advect`'s frame folders).
static OUTPUTS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Lists `target`, an output of this run (a file, or a folder of frames), so that an
/// interrupted run removes its unfinished pieces: the library's temporary files for it
/// and its staging folder ([`staging_dir`]). The target itself is never removed.
pub fn register_output(target: &Path) {
    let mut outputs = OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    if !outputs.iter().any(|p| p == target) {
        outputs.push(target.to_path_buf());
    }
}

/// The staging folder of this process for the frame folder `target`:
/// `.{name}.partial-{pid}` beside it, renamed over `target` when complete.
pub fn staging_dir(target: &Path) -> Option<PathBuf> {
    let name = target.file_name()?;
    let parent = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Some(parent.join(format!(
        ".{}.partial-{}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Removes the unfinished pieces of every listed output; returns how many.
fn remove_unfinished() -> usize {
    let outputs = OUTPUTS.lock().unwrap_or_else(|e| e.into_inner());
    outputs
        .iter()
        .map(|target| {
            let staged = staging_dir(target)
                .is_some_and(|dir| dir.is_dir() && std::fs::remove_dir_all(dir).is_ok());
            texsyn::image_io::remove_temporaries(target) + staged as usize
        })
        .sum()
}

/// Installs the handling above (Linux; elsewhere a killed run leaves its temporary
/// files, which the next run to the same output removes). Call first thing in `main`,
/// before any thread is spawned. Failures leave the default handling in place.
#[cfg(target_os = "linux")]
pub fn install() {
    // SAFETY: plain libc calls on a local, initialized signal set.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaddset(&mut set, sig);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        let waiter = std::thread::Builder::new()
            .name("texsyn-signals".into())
            .spawn(move || {
                let mut sig: libc::c_int = 0;
                if libc::sigwait(&set, &mut sig) != 0 {
                    return;
                }
                let removed = remove_unfinished();
                let what = match sig {
                    libc::SIGINT => "interrupted",
                    libc::SIGHUP => "hung up",
                    _ => "terminated",
                };
                super::stderr_line(format_args!(
                    "\n{what}: stopped{}",
                    if removed > 0 {
                        format!(", unfinished outputs removed ({removed})")
                    } else {
                        String::new()
                    }
                ));
                // _exit, not exit: the other threads (the GPU driver's among them) are
                // still running, and no destructor or atexit handler must race them.
                libc::_exit(128 + sig);
            });
        if waiter.is_err() {
            // Nobody would take the signals: unblock them again.
            libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
        }
    }
}

#[cfg(not(target_os = "linux"))]
pub fn install() {}

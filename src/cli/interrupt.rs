//! Ctrl-C and `kill`: remove the outputs in progress before exiting.
//!
//! Outputs are written to temporary files (and `advect` frames to a staging folder) and
//! renamed into place when complete; destructors remove them after errors, but a signal
//! ends the process without running any. So SIGINT, SIGTERM and SIGHUP are blocked in
//! every thread (set before any thread starts, the mask is inherited, the GPU driver's
//! threads included) and taken by one thread that waits for them, removes what
//! [`texsyn::image_io::remove_pending_outputs`] lists and exits with 128 + the signal
//! number, as a shell reports a process killed by it.

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
                let removed = texsyn::image_io::remove_pending_outputs();
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

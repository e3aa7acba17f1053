//! Keeping a CPU device's worker threads apart (Linux, lavapipe).
//!
//! lavapipe runs each compute dispatch on a pool of worker threads, one per core, that
//! take its workgroups one at a time under a lock and sleep between dispatches. A
//! synthesis is a hundred or so short dispatches, so the workers wake each other far
//! more often than the kernel balances load, and the scheduler can leave them all on one
//! core for the whole run while the others idle, nearly doubling the wall time. Which
//! placement a process gets is chance; creating the device on a thread of its own (as
//! `texsyn synth` does, to overlap it with reading the input) makes the slow one usual.
//!
//! So [`GpuContext::with_options`](super::GpuContext::with_options) creates the device on
//! a thread named [`INIT_THREAD_NAME`]: threads the driver starts meanwhile inherit that
//! name (the driver names some of its threads itself, e.g. `llvmpipe-0`; those are left
//! alone), which tells them apart from every other thread of the process without
//! guessing. On a CPU adapter each of those threads is then bound to one core of those
//! the process may use, in turn, so the workers run in parallel. Only devices texsyn
//! creates are touched ([`GpuContext::from_device`](super::GpuContext::from_device) never
//! is), and [`GpuOptions::pin_cpu_threads`](super::context::GpuOptions::pin_cpu_threads)
//! or `TEXSYN_PIN_CPU_THREADS=0` turns it off.

/// The name (at most 15 bytes, the kernel's limit) of the thread that creates texsyn's
/// devices, and so of the unnamed threads the driver starts while it does.
pub const INIT_THREAD_NAME: &str = "texsyn-gpu-init";

/// Binds each thread of this process named `name` to one allowed core, round robin in
/// the order the threads were created. Returns how many threads were bound (0 where
/// there is nothing to spread: one core allowed, one thread, or not Linux).
pub fn pin_threads_named(name: &str) -> usize {
    imp::pin_threads_named(name)
}

#[cfg(target_os = "linux")]
mod imp {
    pub fn pin_threads_named(name: &str) -> usize {
        let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
            return 0;
        };
        let mut tids: Vec<libc::pid_t> = tasks
            .filter_map(|e| {
                let e = e.ok()?;
                let comm = std::fs::read_to_string(e.path().join("comm")).ok()?;
                (comm.trim_end_matches('\n') == name)
                    .then(|| e.file_name().to_str()?.parse().ok())
                    .flatten()
            })
            .collect();
        // Thread ids grow with creation (until they wrap, which only reorders the turns).
        tids.sort_unstable();
        let cpus = allowed_cpus();
        if cpus.len() < 2 || tids.len() < 2 {
            return 0;
        }
        let mut pinned = 0;
        for (i, &tid) in tids.iter().enumerate() {
            // SAFETY: a zeroed cpu_set_t is a valid empty set; CPU_SET writes within it
            // (the index comes from sched_getaffinity, below CPU_SETSIZE), and
            // sched_setaffinity only reads it. A thread that exited meanwhile makes the
            // call fail (ESRCH), which is ignored.
            let ok = unsafe {
                let mut set: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(cpus[i % cpus.len()], &mut set);
                libc::sched_setaffinity(tid, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
            };
            pinned += ok as usize;
        }
        pinned
    }

    /// The cores this process may run on, in increasing order.
    fn allowed_cpus() -> Vec<usize> {
        // SAFETY: sched_getaffinity fills the zeroed set it is given (of the size passed);
        // CPU_ISSET reads within it.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
                return Vec::new();
            }
            (0..libc::CPU_SETSIZE as usize)
                .filter(|&c| libc::CPU_ISSET(c, &set))
                .collect()
        }
    }
}

#[cfg(not(target_os = "linux"))]
mod imp {
    pub fn pin_threads_named(_name: &str) -> usize {
        0
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// Threads of one name are spread over the allowed cores, one each in turn; other
    /// threads are not touched.
    #[test]
    fn threads_of_one_name_are_spread_over_the_cores() {
        use std::sync::{Arc, Barrier, Mutex};
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let rx = Arc::new(Mutex::new(rx));
        // A thread's name is set by the thread itself as it starts: wait for all four.
        let started = Arc::new(Barrier::new(5));
        let spawn = |name: &str| {
            let (rx, started) = (rx.clone(), started.clone());
            std::thread::Builder::new()
                .name(name.into())
                .spawn(move || {
                    started.wait();
                    let _ = rx.lock().unwrap().recv();
                })
                .unwrap()
        };
        let named: Vec<_> = (0..3).map(|_| spawn("texsyn-pin-test")).collect();
        let other = spawn("texsyn-other");
        started.wait();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let pinned = pin_threads_named("texsyn-pin-test");
        if cores >= 2 {
            assert_eq!(pinned, 3);
        } else {
            assert_eq!(pinned, 0);
        }
        assert_eq!(pin_threads_named("texsyn-no-such-thread"), 0);
        for _ in 0..4 {
            let _ = tx.send(());
        }
        for t in named.into_iter().chain([other]) {
            t.join().unwrap();
        }
    }
}

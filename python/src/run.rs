//! Running long work (a render, a sweep) off the Python thread: the work runs on its own
//! thread (and its rayon pool) while the calling thread, with the GIL released, waits in
//! short slices; between slices it checks for signals (Ctrl-C raises `KeyboardInterrupt`,
//! which sets the renderer's cancel flag: the render stops at its next tile, as the CLI's
//! Ctrl-C) and calls the optional progress callback. Other Python threads run meanwhile, and
//! no worker ever needs the GIL, so the pool cannot deadlock on it.

use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

/// How often signals and the progress callback are looked at (Ctrl-C is answered within
/// this plus the time the render takes to finish its current tiles).
const SLICE: Duration = Duration::from_millis(50);

/// The work's progress, updated from its threads: (done, total) tiles.
#[derive(Default)]
pub struct Progress {
    done: AtomicU64,
    total: AtomicU64,
}

impl Progress {
    pub fn set(&self, done: u64, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        self.done.store(done, Ordering::Relaxed);
    }
    fn get(&self) -> (u64, u64) {
        (self.done.load(Ordering::Relaxed), self.total.load(Ordering::Relaxed))
    }
}

/// Runs `job(cancel, progress)` on another thread; returns its result, or the Python
/// exception that cancelled it (`KeyboardInterrupt`, or one raised by `callback`).
pub fn cancellable<T: Send>(
    py: Python<'_>,
    callback: Option<&Bound<'_, PyAny>>,
    job: impl FnOnce(&AtomicBool, &Progress) -> T + Send,
) -> PyResult<T> {
    let cancel = AtomicBool::new(false);
    let finished = AtomicBool::new(false);
    let progress = Progress::default();
    std::thread::scope(|s| {
        let handle = s.spawn(|| {
            // Set when the job ends, even by a panic (the waiting loop must not spin forever).
            let _done = SetOnDrop(&finished);
            job(&cancel, &progress)
        });
        let mut raised: Option<PyErr> = None;
        let mut last = (u64::MAX, u64::MAX);
        loop {
            py.detach(|| {
                let t0 = std::time::Instant::now();
                while !finished.load(Ordering::SeqCst) && t0.elapsed() < SLICE {
                    std::thread::sleep(Duration::from_millis(5));
                }
            });
            if finished.load(Ordering::SeqCst) {
                break;
            }
            if raised.is_some() {
                continue;
            }
            if let Err(e) = py.check_signals() {
                cancel.store(true, Ordering::SeqCst);
                raised = Some(e);
                continue;
            }
            if let Some(cb) = callback {
                let now = progress.get();
                if now != last && now.1 > 0 {
                    last = now;
                    if let Err(e) = cb.call1(now) {
                        cancel.store(true, Ordering::SeqCst);
                        raised = Some(e);
                    }
                }
            }
        }
        let out = py.detach(|| handle.join());
        if let Some(e) = raised {
            return Err(e);
        }
        let out = out.map_err(|_| pyo3::exceptions::PyRuntimeError::new_err("the render thread panicked"))?;
        if let Some(cb) = callback {
            let (done, total) = progress.get();
            if total > 0 && (done, total) != last {
                cb.call1((done, total))?;
            }
        }
        Ok(out)
    })
}

/// Sets its flag when dropped.
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

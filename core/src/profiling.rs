//! Where a render's time goes, when asked (`penumbra render --phases`; off, each call costs
//! one thread-local load and a branch), cheaply: per-thread counters of the calls of each [`Phase`]
//! (ray queries, shading, light sampling) and the time of about one call in 64, picked by a
//! per-thread xorshift generator (so periodic call patterns do not alias) and timed with
//! `Instant` (vDSO, no system call). No atomics per call: each thread's counters are plain
//! thread-local cells, added to a process-wide total under a lock when a worker pool ends
//! ([`flush`], called by `integrator::with_threads` on every worker) and read by [`take`]. Calls inside a timed call are counted but not
//! timed again (their time is the outer phase's). The estimates are statistics, not
//! measurements: a phase's seconds = its timed seconds × calls / timed calls, timed calls
//! longer than 200 µs (a descheduled thread) left out.

use std::cell::Cell;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// What a call was doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// A camera ray's generation (the driver's `Camera::generate_ray`).
    CameraRay,
    /// The first closest-hit query after the driver hands an estimator a camera ray.
    CameraHit,
    /// Every other closest-hit query.
    ClosestHit,
    /// Occlusion (shadow) queries.
    Shadow,
    /// BSDF construction (materials, textures) and evaluation/sampling.
    Shading,
    /// Light sampling, light pdfs and infinite lights' radiance.
    LightSampling,
}

const N: usize = 6;
const NAMES: [&str; N] = ["camera_ray", "camera_hit", "closest_hit", "shadow", "shading", "light_sampling"];
/// A call is timed when the generator's low bits are 0: one in 64.
const SAMPLE_MASK: u32 = 63;
/// A timed call longer than this (200 µs) is taken for the thread being descheduled and is
/// left out of the estimate, as if it had not been timed: ×64, one preempted call would
/// otherwise count for seconds.
const OUTLIER_NANOS: u64 = 200_000;

/// One phase's totals: calls, timed calls and their seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTotals {
    pub calls: u64,
    pub timed: u64,
    pub timed_seconds: f64,
}

impl PhaseTotals {
    /// The estimated thread-seconds of all calls.
    pub fn seconds(&self) -> f64 {
        if self.timed == 0 {
            0.0
        } else {
            self.timed_seconds * self.calls as f64 / self.timed as f64
        }
    }
}

/// Every phase's totals, as `stats.json` writes them (`{"shadow": {"calls", "seconds"}, …}`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Phases(pub [PhaseTotals; N]);

impl Phases {
    pub fn get(&self, p: Phase) -> PhaseTotals {
        self.0[p as usize]
    }
    fn add(&mut self, o: &Phases) {
        for (a, b) in self.0.iter_mut().zip(&o.0) {
            a.calls += b.calls;
            a.timed += b.timed;
            a.timed_seconds += b.timed_seconds;
        }
    }
}

impl serde::Serialize for Phases {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let map: BTreeMap<&str, BTreeMap<&str, f64>> = NAMES
            .iter()
            .zip(&self.0)
            .filter(|(_, t)| t.calls > 0)
            .map(|(n, t)| (*n, BTreeMap::from([("calls", t.calls as f64), ("seconds", t.seconds())])))
            .collect();
        map.serialize(s)
    }
}

struct Local {
    calls: [Cell<u64>; N],
    timed: [Cell<u64>; N],
    nanos: [Cell<u64>; N],
    rng: Cell<u32>,
    /// This thread records ([`enable_here`]); off, a call costs one thread-local load.
    enabled: Cell<bool>,
    active: Cell<bool>,
    camera_pending: Cell<bool>,
}

thread_local! {
    static LOCAL: Local = const {
        Local {
            calls: [const { Cell::new(0) }; N],
            timed: [const { Cell::new(0) }; N],
            nanos: [const { Cell::new(0) }; N],
            rng: Cell::new(0x9e37_79b9),
            enabled: Cell::new(false),
            active: Cell::new(false),
            camera_pending: Cell::new(false),
        }
    };
}

/// Whether renders record phases (`penumbra render --phases`); read once per worker pool.
static ENABLED: AtomicBool = AtomicBool::new(false);

/// Turns recording on or off for the worker pools started from now on (and this thread).
pub fn set_enabled(on: bool) {
    ENABLED.store(on, Ordering::Relaxed);
    enable_here(on);
}

/// Whether [`set_enabled`] turned recording on.
pub fn enabled() -> bool {
    ENABLED.load(Ordering::Relaxed)
}

/// Turns recording on or off for the calling thread (`integrator::with_threads` does it on
/// every worker, from [`enabled`]).
pub fn enable_here(on: bool) {
    LOCAL.with(|l| l.enabled.set(on));
}

static GLOBAL: Mutex<Phases> = Mutex::new(Phases([PhaseTotals { calls: 0, timed: 0, timed_seconds: 0.0 }; N]));

/// Runs `f` as a call of `phase`: counted, and timed about one time in 64.
#[inline]
pub fn timed<R>(phase: Phase, f: impl FnOnce() -> R) -> R {
    let time = LOCAL.with(|l| {
        if !l.enabled.get() {
            return false;
        }
        let i = phase as usize;
        l.calls[i].set(l.calls[i].get() + 1);
        let mut x = l.rng.get();
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        l.rng.set(x);
        x & SAMPLE_MASK == 0 && !l.active.replace(true)
    });
    if !time {
        return f();
    }
    let start = Instant::now();
    let r = f();
    let ns = start.elapsed().as_nanos() as u64;
    LOCAL.with(|l| {
        let i = phase as usize;
        if ns <= OUTLIER_NANOS {
            l.timed[i].set(l.timed[i].get() + 1);
            l.nanos[i].set(l.nanos[i].get() + ns);
        }
        l.active.set(false);
    });
    r
}

/// A closest-hit query: [`Phase::CameraHit`] when it is the first since [`camera_ray_given`].
#[inline]
pub fn closest_hit<R>(f: impl FnOnce() -> R) -> R {
    let camera = LOCAL.with(|l| l.enabled.get() && l.camera_pending.replace(false));
    timed(if camera { Phase::CameraHit } else { Phase::ClosestHit }, f)
}

/// The driver hands an estimator a camera ray (`true`) or has taken it back (`false`).
#[inline]
pub fn camera_ray_given(pending: bool) {
    LOCAL.with(|l| l.camera_pending.set(pending));
}

/// Adds this thread's counters to the process-wide totals and resets them.
pub fn flush() {
    let mut mine = Phases::default();
    LOCAL.with(|l| {
        for i in 0..N {
            mine.0[i] = PhaseTotals {
                calls: l.calls[i].replace(0),
                timed: l.timed[i].replace(0),
                timed_seconds: l.nanos[i].replace(0) as f64 * 1e-9,
            };
        }
    });
    if let Ok(mut g) = GLOBAL.lock() {
        g.add(&mine);
    }
}

/// The process-wide totals since the last `take` (this thread's counters flushed first), reset.
pub fn take() -> Phases {
    flush();
    GLOBAL.lock().map(|mut g| std::mem::take(&mut *g)).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_every_call_and_times_some() {
        std::thread::spawn(|| {
            // Off (the default), nothing is counted.
            timed(Phase::Shading, || ());
            LOCAL.with(|l| assert_eq!(l.calls[Phase::Shading as usize].get(), 0));
            enable_here(true);
            let mut x = 0u64;
            for i in 0..64_000u64 {
                x = timed(Phase::Shading, || x.wrapping_add(i));
                // Nested calls are counted, never timed on their own.
                timed(Phase::Shadow, || timed(Phase::LightSampling, || ()));
            }
            camera_ray_given(true);
            closest_hit(|| ());
            closest_hit(|| ());
            let mut mine = Phases::default();
            LOCAL.with(|l| {
                for i in 0..N {
                    mine.0[i].calls = l.calls[i].get();
                    mine.0[i].timed = l.timed[i].get();
                }
            });
            assert_eq!(mine.get(Phase::Shading).calls, 64_000);
            assert_eq!(mine.get(Phase::LightSampling).calls, 64_000);
            for p in [Phase::Shading, Phase::Shadow, Phase::LightSampling] {
                let t = mine.get(p).timed;
                assert!((700..1300).contains(&t), "{p:?}: {t} of 64000 timed");
            }
            // Inside a timed call (`active`), calls are counted and never timed.
            LOCAL.with(|l| l.active.set(true));
            for _ in 0..10_000 {
                timed(Phase::CameraRay, || ());
            }
            LOCAL.with(|l| {
                assert_eq!((l.calls[0].get(), l.timed[0].get()), (10_000, 0));
                assert!(l.active.get(), "a nested call must not end the outer timing");
            });
            assert_eq!((mine.get(Phase::CameraHit).calls, mine.get(Phase::ClosestHit).calls), (1, 1));
            std::hint::black_box(x);
        })
        .join()
        .unwrap();
    }
}

//! Experiments: the ablation grid, the main job, the full protocol and the sim-to-real loop. They generate data, train
//! and evaluate through `data`, `train` and `eval`; `eval` itself only scores.
pub mod ablate;
pub mod device_loop;
pub mod protocol;
pub mod quickstart;
pub mod sweep;

use crate::error::Result;

/// `f(i, item)` for every item, at most `jobs` at once, taken in order; the results in the
/// items' order. The first error stops new items (running ones finish) and is returned.
pub(crate) fn at_once<T: Sync, R: Send>(
    jobs: usize,
    items: &[T],
    f: impl Fn(usize, &T) -> Result<R> + Sync,
) -> Result<Vec<R>> {
    use std::sync::Mutex;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::SeqCst};
    if jobs <= 1 {
        return items.iter().enumerate().map(|(i, t)| f(i, t)).collect();
    }
    let (next, failed) = (AtomicUsize::new(0), AtomicBool::new(false));
    let done: Mutex<Vec<(usize, Result<R>)>> = Mutex::default();
    std::thread::scope(|scope| {
        for _ in 0..jobs.min(items.len()) {
            scope.spawn(|| {
                while !failed.load(SeqCst) {
                    let i = next.fetch_add(1, SeqCst);
                    let Some(item) = items.get(i) else { break };
                    let r = f(i, item);
                    failed.fetch_or(r.is_err(), SeqCst);
                    done.lock().unwrap_or_else(|e| e.into_inner()).push((i, r));
                }
            });
        }
    });
    let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

//! Experiments: the ablation grid, the main job, the full protocol and the sim-to-real loop. They generate data, train
//! and evaluate through `data`, `train` and `eval`; `eval` itself only scores.
pub mod ablate;
pub mod device_loop;
pub mod presets;
pub mod protocol;
pub mod quickstart;
pub mod recipe;
pub mod sweep;

use crate::error::Result;

/// `f(i, item)` for every item, at most `jobs` at once, taken in order; the results in the
/// items' order. The first error stops new items (running ones finish) and is returned.
///
/// Each job runs in a thread pool of its own, as wide as the global one: a job's serial work
/// and its parallel operations then stay on its own threads, as in a process of its own.
/// Through the one global pool, three small trainings at once took 1.5× as long, every
/// parallel operation handed to the pool and back.
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
                let work = || {
                    while !failed.load(SeqCst) {
                        let i = next.fetch_add(1, SeqCst);
                        let Some(item) = items.get(i) else { break };
                        let r = f(i, item);
                        failed.fetch_or(r.is_err(), SeqCst);
                        done.lock().unwrap_or_else(|e| e.into_inner()).push((i, r));
                    }
                };
                // Without a pool of its own (none could be made), the job shares the global one.
                match rayon::ThreadPoolBuilder::new()
                    .num_threads(rayon::current_num_threads())
                    .build()
                {
                    Ok(pool) => pool.install(work),
                    Err(_) => work(),
                }
            });
        }
    });
    let mut done = done.into_inner().unwrap_or_else(|e| e.into_inner());
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn each_job_runs_inside_a_pool_as_wide_as_the_global_one() {
        let global = rayon::current_num_threads();
        let items = [1, 2, 3, 4, 5];
        let seen = super::at_once(2, &items, |i, &x| {
            Ok((
                i,
                x,
                rayon::current_thread_index().is_some(),
                rayon::current_num_threads(),
            ))
        })
        .unwrap();
        for (i, &(at, x, in_pool, width)) in seen.iter().enumerate() {
            assert_eq!((at, x), (i, items[i]), "results in the items' order");
            assert!(in_pool, "item {i} ran outside a pool");
            assert_eq!(width, global);
        }
    }
}

//! Reproducible initialisation. Burn draws every random number of a backend from one generator
//! that all threads share (flex's `SEED`), and some initialisers draw when a layer is built,
//! others at a parameter's first use. A network built while another thread draws would take
//! some of that thread's numbers. So every network here is built under one lock and draws all
//! its parameters before the lock is released: a seeded initialisation gives the same weights
//! whatever else the process runs, and an unseeded one never takes a seeded one's numbers.

use crate::error::Result;
use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Bool, Device, Int, Tensor};
use std::cell::Cell;
use std::sync::Mutex;

static DRAWS: Mutex<()> = Mutex::new(());

thread_local! {
    /// Whether this thread holds `DRAWS` (a seeded initialisation builds its network inside).
    static HELD: Cell<bool> = const { Cell::new(false) };
}

/// Runs `build` under the draw lock (re-entrant on one thread) and reads every parameter of
/// what it built, so that no draw is left for later.
pub(crate) fn drawing<M: Module>(build: impl FnOnce() -> Result<M>) -> Result<M> {
    /// Clears `HELD` on every exit, panics included.
    struct Release;
    impl Drop for Release {
        fn drop(&mut self) {
            HELD.set(false);
        }
    }
    let _held = (!HELD.get()).then(|| {
        let guard = DRAWS.lock().unwrap_or_else(|e| e.into_inner());
        HELD.set(true);
        (guard, Release)
    });
    let module = build()?;
    module.visit(&mut Materialise);
    Ok(module)
}

/// `init` run right after seeding `device`'s generator with `seed`, under the draw lock: the
/// same seed gives the same weights in any process, beside any other work.
pub fn seeded_init<M: Module>(
    device: &Device,
    seed: u64,
    init: impl FnOnce() -> Result<M>,
) -> Result<M> {
    drawing(|| {
        device.seed(seed);
        init()
    })
}

/// Reads every parameter once, which makes Burn run its deferred initialisation.
struct Materialise;

impl ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let _ = param.val();
    }
    fn visit_int<const D: usize>(&mut self, param: &Param<Tensor<D, Int>>) {
        let _ = param.val();
    }
    fn visit_bool<const D: usize>(&mut self, param: &Param<Tensor<D, Bool>>) {
        let _ = param.val();
    }
}

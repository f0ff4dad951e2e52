//! What the flex kernels (`conv`, `batch_norm`) share to write one output from parallel tasks.

/// A pointer to an output that parallel tasks write in disjoint places.
#[derive(Clone, Copy)]
pub(crate) struct Shared(pub(crate) *mut f32);
// SAFETY: every user writes through it only at positions no other task touches.
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}
impl Shared {
    /// Through a method, so closures capture the whole (Sync) wrapper, not its field.
    pub(crate) fn at(self, offset: usize) -> *mut f32 {
        self.0.wrapping_add(offset)
    }
}

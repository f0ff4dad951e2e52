//! What the flex kernels (`conv`, `batch_norm`, `train::fused_loss`) share: the pointer their
//! parallel tasks write one output through, and the tensor the output becomes.

use burn::backend::Flex;
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::tensor::{Shape, TensorData};

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

    /// `n` elements from `offset`.
    ///
    /// # Safety
    /// The range is inside the buffer, and no other task touches it while the slice lives.
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn slice<'a>(self, offset: usize, n: usize) -> &'a mut [f32] {
        // SAFETY: forwarded from the caller.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(offset), n) }
    }
}

/// A flex tensor of `shape` holding `data`.
pub(crate) fn flex_tensor(data: Vec<f32>, shape: impl Into<Shape>) -> FloatTensor<Flex> {
    Flex::float_from_data(TensorData::new(data, shape), &Default::default())
}

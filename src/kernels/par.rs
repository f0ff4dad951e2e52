//! What the flex kernels (`conv`, `winograd`, `direct`, `batch_norm`, `kernels::fused_loss`)
//! share: the pointer their parallel tasks write one output through, the tensor the output
//! becomes, the GEMM call, AVX2 compilation and zero-padded row copies.

use burn::backend::Flex;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::Ops;
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

/// dst[m×n] = lhs[m×k] · rhs[k×n] (plus dst when `accumulate`), each matrix given by its
/// (column, row) strides, no conjugation; on the rayon pool when `parallel`, else on the
/// calling thread.
///
/// # Safety
/// Every stride and extent must index inside the three buffers.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn matmul(
    [m, n, k]: [usize; 3],
    dst: *mut f32,
    [dst_cs, dst_rs]: [isize; 2],
    accumulate: bool,
    lhs: *const f32,
    [lhs_cs, lhs_rs]: [isize; 2],
    rhs: *const f32,
    [rhs_cs, rhs_rs]: [isize; 2],
    parallel: bool,
) {
    let parallelism = if parallel {
        gemm::Parallelism::Rayon(0)
    } else {
        gemm::Parallelism::None
    };
    // SAFETY: forwarded from the caller. alpha (the weight on dst) is 1 when accumulating
    // and ignored by gemm otherwise.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst,
            dst_cs,
            dst_rs,
            accumulate,
            lhs,
            lhs_cs,
            lhs_rs,
            rhs,
            rhs_cs,
            rhs_rs,
            1.0,
            1.0,
            false,
            false,
            false,
            parallelism,
        )
    }
}

/// `f()`, compiled for AVX2 where the CPU has it: the kernels' fixed-size array loops then run
/// 8 lanes per instruction instead of SSE2's 4. The bits are the same either way (Rust never
/// contracts a·b + c into an FMA), so results do not depend on the machine's vector width.
/// `f` and what it calls must be `#[inline(always)]` (or small enough to inline) to be compiled
/// inside the AVX2 function.
#[inline(always)]
pub(crate) fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        fn inner<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        static AVX2: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        if *AVX2.get_or_init(|| std::is_x86_feature_detected!("avx2")) {
            // SAFETY: the CPU has AVX2 (checked above).
            return unsafe { inner(f) };
        }
    }
    f()
}

/// Copies the plane's rows y0 − pt … (as many as `padded` holds, `wp` wide, from column −pl)
/// into `padded`, zero outside the plane.
pub(crate) fn pad_rows(
    plane: &[f32],
    [h, w]: [usize; 2],
    [y0, pt, pl]: [usize; 3],
    wp: usize,
    padded: &mut [f32],
) {
    for (r, dst) in padded.chunks_exact_mut(wp).enumerate() {
        let iy = (y0 + r) as isize - pt as isize;
        if iy < 0 || iy >= h as isize {
            dst.fill(0.0);
            continue;
        }
        let src = &plane[iy as usize * w..][..w];
        // dst[c] = src[c − pl] where that is inside the row.
        let lo = pl.min(wp);
        let hi = (pl + w).min(wp);
        dst[..lo].fill(0.0);
        dst[lo..hi].copy_from_slice(&src[..hi - lo]);
        dst[hi..].fill(0.0);
    }
}

/// The autodiff step of a flex op with one input and no checkpointed tensors (`kernels::pad`,
/// `kernels::pool`): registers dL/dx = `dx(dL/dy, state)` where x is tracked.
pub(crate) fn unary_backward<S>(
    ops: Ops<S, 1>,
    grads: &mut Gradients,
    dx: impl FnOnce(FloatTensor<Flex>, S) -> FloatTensor<Flex>,
) {
    let [node_x] = ops.parents;
    let grad = grads.consume::<Flex>(&ops.node);
    if let Some(node) = node_x {
        grads.register::<Flex>(node.id, dx(grad, ops.state));
    }
}

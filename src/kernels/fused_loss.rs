//! Network-1's loss as one operation on flex.
//!
//! Every reading of `train::loss::network1_loss` is a softmax over the 256 classes followed by
//! a per-pixel loss. Composed from tensor operations, that is a dozen serial passes over the
//! B×256×H×W logits forward and as many backward (`cargo bench --bench train_ops`). Here each pixel's loss comes from its column of logits in
//! one parallel pass (max, then exp-sum), keeping only its log-sum-exp; the backward
//! recomputes p_c = exp(z_c − lse) and writes dℓ/dz_c in closed form:
//!
//! ```text
//!   literal   ℓ = 2α(1 − p_t)           dℓ/dz_c = 2α·p_t·(p_c − δ_ct)
//!   cross-ent ℓ = α(lse − z_t)          dℓ/dz_c = α·(p_c − δ_ct)
//!   soft      ℓ = α(lse − Σ_c q_c z_c)  dℓ/dz_c = α·(p_c − q_c)          (Σ q = 1)
//!   ordinal   ℓ = α|E − t/(C−1)|        dℓ/dz_c = α·sign(E − t/(C−1))·p_c·(c/(C−1) − E)
//! ```
//!
//! with E = Σ p_c·c/(C−1). The exponential is a branch-free polynomial ([`exp`]) so the loops
//! vectorise; every sum runs over the classes in order per pixel, so results do not depend on
//! the thread count or the vector width. Other backends compose the loss from Burn's operations
//! (`train/loss.rs`), which the tests compare this with.

use crate::kernels::par::{Shared, flex_tensor};
use burn::backend::autodiff::Autodiff;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::{Dispatch, Flex, TensorMetadata, backend_extension};
use burn::tensor::{DType, Int, Tensor};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// How the Network-1 loss reads its 256 classes (`[loss] reading`, docs/network1.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Network1Reading {
    /// Paper Eq. 4 as written: α_t · Σ_c |p_c − 1[c = t]| = 2α_t(1 − p_t) (`train::loss::weighted_l1`).
    Literal,
    /// α_t · |Σ_c p_c·c/(C−1) − t/(C−1)|: L1 of the expected blend weight (`train::loss::ordinal_l1`).
    Ordinal,
    /// α_t · (−log p_t) (`train::loss::weighted_cross_entropy`).
    CrossEntropy,
    /// α_t · (−Σ_c q_c log p_c) with q a Gaussian over class indices around t
    /// (`train::loss::soft_cross_entropy`).
    #[default]
    Soft,
}

/// The per-pixel loss of one reading (`sigma`: the soft labels' width in classes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassLoss {
    pub reading: Network1Reading,
    pub sigma: f32,
}

/// Per-pixel loss α_t·ℓ of `logits` [B, C, H, W] against `target` [B, H, W] (class indices)
/// with class weights `alpha` [C]: [B, H, W].
#[backend_extension(Flex, Autodiff)]
pub trait FlexClassLoss: burn::backend::Backend {
    fn class_loss(
        logits: FloatTensor<Self>,
        target: IntTensor<Self>,
        alpha: FloatTensor<Self>,
        loss: ClassLoss,
    ) -> FloatTensor<Self>;
}

impl FlexClassLoss for Flex {
    fn class_loss(
        logits: FloatTensor<Self>,
        target: IntTensor<Self>,
        alpha: FloatTensor<Self>,
        loss: ClassLoss,
    ) -> FloatTensor<Self> {
        forward(logits, target, alpha, loss).0
    }
}

/// What the backward needs besides the logits: targets, α, and per pixel the log-sum-exp and
/// the reading's own value (p_t for literal, E for ordinal).
#[derive(Clone, Debug)]
struct Saved {
    target: Arc<[u32]>,
    alpha: Arc<[f32]>,
    lse: Arc<[f32]>,
    aux: Arc<[f32]>,
    /// The soft reading's labels ([`soft_labels`]), computed once per step.
    q: Option<Arc<[f32]>>,
}

#[derive(Debug)]
struct ClassLossOp;

impl Backward<Flex, 1> for ClassLossOp {
    type State = (NodeId, Saved, ClassLoss);

    fn backward(
        self,
        ops: Ops<Self::State, 1>,
        grads: &mut Gradients,
        checkpointer: &mut Checkpointer,
    ) {
        let [node_logits] = ops.parents;
        let grad = grads.consume::<Flex>(&ops.node);
        let (logits_state, saved, loss) = ops.state;
        let logits = checkpointer.retrieve_node_output::<FloatTensor<Flex>>(logits_state);
        if let Some(node) = node_logits {
            grads.register::<Flex>(node.id, backward(logits, grad, &saved, loss));
        }
    }
}

impl<C: CheckpointStrategy> FlexClassLoss for Autodiff<Flex, C> {
    fn class_loss(
        logits: FloatTensor<Self>,
        target: IntTensor<Self>,
        alpha: FloatTensor<Self>,
        loss: ClassLoss,
    ) -> FloatTensor<Self> {
        match ClassLossOp
            .prepare::<C>([logits.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(mut prep) => {
                let logits_state = prep.checkpoint(&logits);
                let (out, saved) = forward(
                    logits.into_primitive(),
                    target,
                    alpha.into_primitive(),
                    loss,
                );
                prep.finish((logits_state, saved, loss), out)
            }
            OpsKind::UnTracked(prep) => prep.finish(
                forward(
                    logits.into_primitive(),
                    target,
                    alpha.into_primitive(),
                    loss,
                )
                .0,
            ),
        }
    }
}

/// [`FlexClassLoss::class_loss`] when every tensor lives on flex with f32 logits and α, and
/// i32/i64 targets inside 0..C; `None` otherwise (the caller composes the loss instead).
pub fn class_loss(
    logits: &Tensor<4>,
    target: &Tensor<3, Int>,
    alpha: &Tensor<1>,
    loss: ClassLoss,
) -> Option<Tensor<3>> {
    let device = logits.device();
    if !crate::device::is_flex(&device)
        || logits.dtype() != DType::F32
        || alpha.dtype() != DType::F32
    {
        return None;
    }
    let [b, c, h, w] = logits.dims();
    if target.dims() != [b, h, w]
        || alpha.dims() != [c]
        || !matches!(target.dtype(), DType::I32 | DType::I64)
    {
        return None;
    }
    Some(Tensor::from_dispatch(
        <Dispatch as FlexClassLoss>::class_loss(
            logits.clone().into_dispatch(),
            target.clone().into_dispatch(),
            alpha.clone().into_dispatch(),
            loss,
        ),
    ))
}

/// Pixels per task: 256 classes × 512 pixels of f32 (512 KiB) stay in L2 between the max and
/// the exp-sum pass, and each class's run of 2 KiB is long enough for the prefetcher (64 pixels,
/// 256-byte runs 64 KiB apart, were slower in both losses, `cargo bench --bench train_ops`).
const BLOCK: usize = 512;

/// e^x for the softmax's x ≤ 0 (any x in [−87, 88]; below −87 it returns e^−87 ≈ 1.6e−38,
/// which no sum of 256 terms notices): Cephes' expf, 2^k·P(r) with |r| ≤ ln2/2, within 2 ulp.
/// Straight-line f32 arithmetic, so loops over it vectorise and give the same bits at any
/// vector width.
#[inline(always)]
pub fn exp(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // Adding and subtracting 1.5·2^23 rounds to the nearest integer.
    const ROUND: f32 = 12_582_912.0;
    let x = if x < -87.0 { -87.0 } else { x };
    let x = if x > 88.0 { 88.0 } else { x };
    let k = (x * LOG2E + ROUND) - ROUND;
    // ln 2 in two parts, so r = x − k·ln2 keeps its low bits.
    let r = x - k * 0.693_359_4 - k * -2.121_944_4e-4;
    let p = ((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r
        + 1.666_666_5e-1)
        * r
        + 0.5;
    let p = p * (r * r) + r + 1.0;
    p * f32::from_bits(((k as i32 + 127) << 23) as u32)
}

/// Soft-label weights qᵀ[c·C + t] = q_c for target t: a Gaussian over class indices around t,
/// normalised over the C classes (in f64).
fn soft_labels(c: usize, sigma: f32) -> Vec<f32> {
    let s2 = 2.0 * (sigma.max(1e-3) as f64).powi(2);
    let mut q = vec![0.0f32; c * c];
    for t in 0..c {
        let g: Vec<f64> = (0..c)
            .map(|k| (-((k as f64 - t as f64).powi(2)) / s2).exp())
            .collect();
        let sum: f64 = g.iter().sum();
        for (k, v) in g.iter().enumerate() {
            q[k * c + t] = (v / sum) as f32;
        }
    }
    q
}

/// The pixel blocks (batch item, first pixel, pixels) in a fixed order.
fn blocks(batch: usize, pixels: usize) -> Vec<(usize, usize, usize)> {
    (0..batch)
        .flat_map(|b| {
            (0..pixels)
                .step_by(BLOCK)
                .map(move |p0| (b, p0, BLOCK.min(pixels - p0)))
        })
        .collect()
}

fn targets(target: IntTensor<Flex>, classes: usize) -> Option<Vec<u32>> {
    let target = target.to_contiguous();
    let in_range = |v: i64| (0..classes as i64).contains(&v).then_some(v as u32);
    match target.dtype() {
        DType::I32 => target
            .storage::<i32>()
            .iter()
            .map(|&v| in_range(v as i64))
            .collect(),
        DType::I64 => target
            .storage::<i64>()
            .iter()
            .map(|&v| in_range(v))
            .collect(),
        _ => None,
    }
}

/// The per-pixel losses [B, H, W] and what the backward needs.
fn forward(
    logits: FloatTensor<Flex>,
    target: IntTensor<Flex>,
    alpha: FloatTensor<Flex>,
    loss: ClassLoss,
) -> (FloatTensor<Flex>, Saved) {
    let [b, c, h, w]: [usize; 4] = logits.shape().dims();
    let p_all = h * w;
    let target: Arc<[u32]> = targets(target, c)
        .expect("Network-1 loss: every target class must be in 0..C")
        .into();
    let alpha: Arc<[f32]> = alpha.to_contiguous().storage::<f32>().into();
    let logits = logits.to_contiguous();
    let z = logits.storage::<f32>();
    let q: Option<Arc<[f32]>> =
        (loss.reading == Network1Reading::Soft).then(|| soft_labels(c, loss.sigma).into());
    let level = |k: usize| k as f32 / (c - 1).max(1) as f32;
    let (mut out, mut lse, mut aux) = (
        vec![0.0f32; b * p_all],
        vec![0.0f32; b * p_all],
        vec![0.0f32; b * p_all],
    );
    let (o, l, a) = (
        Shared(out.as_mut_ptr()),
        Shared(lse.as_mut_ptr()),
        Shared(aux.as_mut_ptr()),
    );
    blocks(b, p_all).into_par_iter().for_each(|(bi, p0, n)| {
        let col = |k: usize| &z[(bi * c + k) * p_all + p0..][..n];
        let t = &target[bi * p_all + p0..][..n];
        let mut m = [f32::NEG_INFINITY; BLOCK];
        for k in 0..c {
            for (m, &v) in m.iter_mut().zip(col(k)) {
                *m = if v > *m { v } else { *m };
            }
        }
        let (mut s, mut acc) = ([0.0f32; BLOCK], [0.0f32; BLOCK]);
        for k in 0..c {
            if loss.reading == Network1Reading::Ordinal {
                let lv = level(k);
                for (((s, acc), &m), &v) in s.iter_mut().zip(&mut acc).zip(&m).zip(col(k)) {
                    let e = exp(v - m);
                    *s += e;
                    *acc += e * lv;
                }
                continue;
            }
            for ((s, &m), &v) in s.iter_mut().zip(&m).zip(col(k)) {
                *s += exp(v - m);
            }
            if let Some(q) = &q {
                let qk = &q[k * c..(k + 1) * c];
                for ((acc, &ti), &v) in acc.iter_mut().zip(t).zip(col(k)) {
                    *acc += qk[ti as usize] * v;
                }
            }
        }
        // SAFETY: block (bi, p0, n) is this task's alone, inside the [B·H·W] outputs.
        let (out, lse, aux) = unsafe {
            let at = bi * p_all + p0;
            (o.slice(at, n), l.slice(at, n), a.slice(at, n))
        };
        for j in 0..n {
            let (ti, ai) = (t[j] as usize, alpha[t[j] as usize]);
            let zt = z[(bi * c + ti) * p_all + p0 + j];
            lse[j] = m[j] + s[j].ln();
            out[j] = match loss.reading {
                Network1Reading::Literal => {
                    aux[j] = exp(zt - m[j]) / s[j];
                    2.0 * ai * (1.0 - aux[j])
                }
                Network1Reading::CrossEntropy => ai * (lse[j] - zt),
                Network1Reading::Soft => ai * (lse[j] - acc[j]),
                Network1Reading::Ordinal => {
                    aux[j] = acc[j] / s[j];
                    ai * (aux[j] - level(ti)).abs()
                }
            };
        }
    });
    let saved = Saved {
        target,
        alpha,
        lse: lse.into(),
        aux: aux.into(),
        q,
    };
    (flex_tensor(out, [b, h, w]), saved)
}

/// dL/dlogits [B, C, H, W] from the per-pixel gradient `grad` [B, H, W].
fn backward(
    logits: FloatTensor<Flex>,
    grad: FloatTensor<Flex>,
    saved: &Saved,
    loss: ClassLoss,
) -> FloatTensor<Flex> {
    let [b, c, h, w]: [usize; 4] = logits.shape().dims();
    let p_all = h * w;
    let (logits, grad) = (logits.to_contiguous(), grad.to_contiguous());
    let (z, g) = (logits.storage::<f32>(), grad.storage::<f32>());
    let level = |k: usize| k as f32 / (c - 1).max(1) as f32;
    let mut dz = vec![0.0f32; b * c * p_all];
    let d = Shared(dz.as_mut_ptr());
    blocks(b, p_all).into_par_iter().for_each(|(bi, p0, n)| {
        let at = bi * p_all + p0;
        let (t, lse, aux) = (
            &saved.target[at..][..n],
            &saved.lse[at..][..n],
            &saved.aux[at..][..n],
        );
        // k_j: the factor every class's term carries at pixel j.
        let mut f = [0.0f32; BLOCK];
        for j in 0..n {
            let ai = saved.alpha[t[j] as usize];
            f[j] = g[at + j]
                * match loss.reading {
                    Network1Reading::Literal => 2.0 * ai * aux[j],
                    Network1Reading::CrossEntropy | Network1Reading::Soft => ai,
                    Network1Reading::Ordinal => {
                        let e = aux[j] - level(t[j] as usize);
                        ai * if e > 0.0 {
                            1.0
                        } else if e < 0.0 {
                            -1.0
                        } else {
                            0.0
                        }
                    }
                };
        }
        for k in 0..c {
            let row = (bi * c + k) * p_all + p0;
            let zk = &z[row..][..n];
            // SAFETY: class k's row of block (bi, p0, n) is this task's alone, inside dz.
            let out = unsafe { d.slice(row, n) };
            match loss.reading {
                Network1Reading::Ordinal => {
                    let lv = level(k);
                    for j in 0..n {
                        out[j] = f[j] * exp(zk[j] - lse[j]) * (lv - aux[j]);
                    }
                }
                Network1Reading::Soft => {
                    let qk = &saved.q.as_ref().expect("soft labels")[k * c..(k + 1) * c];
                    for j in 0..n {
                        out[j] = f[j] * (exp(zk[j] - lse[j]) - qk[t[j] as usize]);
                    }
                }
                Network1Reading::Literal | Network1Reading::CrossEntropy => {
                    for j in 0..n {
                        out[j] = f[j] * exp(zk[j] - lse[j]);
                    }
                }
            }
        }
        if matches!(
            loss.reading,
            Network1Reading::Literal | Network1Reading::CrossEntropy
        ) {
            // The −δ_ct term, at each pixel's target class.
            for j in 0..n {
                let row = (bi * c + t[j] as usize) * p_all + p0 + j;
                // SAFETY: inside this task's block, as above.
                let v = unsafe { d.slice(row, 1) };
                v[0] = f[j] * (exp(z[row] - lse[j]) - 1.0);
            }
        }
    });
    flex_tensor(dz, [b, c, h, w])
}

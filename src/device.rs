//! Choosing the compute device once, at the edge. Burn 0.22 dispatches on the `Device` at run
//! time, so model code is backend-agnostic; this maps a config/CLI name to a device that the
//! build has compiled in.

use crate::error::{Error, Result};
pub use burn::tensor::Device;

/// Names accepted: "flex" (default CPU), "ndarray", "tch" / "libtorch" (LibTorch CPU), "wgpu",
/// "cuda" / "cuda:N". Only cuda takes an index: wgpu's adapter is the one wgpu picks for high
/// performance, or the one `CUBECL_WGPU_DEFAULT_DEVICE` names (e.g. `DiscreteGpu(1)`, `Cpu`).
pub fn device_from_name(name: &str) -> Result<Device> {
    let (kind, index) =
        match name.split_once(':') {
            Some((k, i)) => (
                k,
                Some(i.parse::<usize>().map_err(|_| {
                    Error::key(format!("device '{name}'"), format!("bad index '{i}'"))
                })?),
            ),
            None => (name, None),
        };
    if index.is_some() && kind != "cuda" {
        return Err(Error::key(
            format!("device '{name}'"),
            format!("only cuda takes an index (cuda:N); write '{kind}'"),
        ));
    }
    match kind {
        #[cfg(feature = "flex")]
        "flex" | "cpu" => Ok(Device::flex()),
        #[cfg(feature = "ndarray")]
        #[allow(deprecated)]
        "ndarray" => Ok(Device::ndarray()),
        #[cfg(feature = "tch")]
        #[allow(deprecated)]
        "tch" | "libtorch" => Ok(Device::libtorch()),
        #[cfg(feature = "wgpu")]
        "wgpu" => wgpu::device(),
        #[cfg(feature = "cuda")]
        "cuda" => Ok(Device::cuda(index.unwrap_or(0))),
        _ => Err(Error::key(
            format!("device '{name}'"),
            format!(
                "not available in this build (compiled in: {}); enable the cargo feature of \
                 the same name",
                compiled_backends().join(", ")
            ),
        )),
    }
}

/// wgpu's device, acquired once per process. Burn's `Device::wgpu` acquires its adapter at the
/// first tensor operation and panics there when there is none; acquiring it here turns a
/// machine without a usable adapter into an error before anything is built or written.
#[cfg(feature = "wgpu")]
mod wgpu {
    use super::{Device, Error, Result};
    use std::sync::OnceLock;

    /// The device and its adapter's description, or why there is none.
    type Acquired = std::result::Result<(Device, String), String>;

    fn acquired() -> &'static Acquired {
        static DEVICE: OnceLock<Acquired> = OnceLock::new();
        DEVICE.get_or_init(|| {
            Device::wgpu_options()
                .init_with_setup()
                .map(|(device, setup)| {
                    let info = setup.adapter.get_info();
                    let what = format!(
                        "{} ({:?}, {:?}, driver {} {})",
                        info.name, info.backend, info.device_type, info.driver, info.driver_info
                    );
                    (device, what)
                })
                .map_err(|e| e.to_string())
        })
    }

    pub fn device() -> Result<Device> {
        match acquired() {
            Ok((device, _)) => Ok(device.clone()),
            Err(why) => Err(Error::key(
                "device 'wgpu'",
                format!(
                    "no usable adapter ({why}). wgpu needs a Vulkan, Metal or DX12 \
                 driver: on Linux the GPU vendor's Vulkan driver, or for a slow CPU one \
                 Debian/Ubuntu's mesa-vulkan-drivers (`vulkaninfo --summary` lists what wgpu \
                 can see); CUBECL_WGPU_DEFAULT_DEVICE picks among several (docs/gpu.md)"
                ),
            )),
        }
    }

    pub fn adapter() -> Option<&'static str> {
        acquired().as_ref().ok().map(|(_, what)| what.as_str())
    }
}

/// The wgpu adapter the device runs on ("llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu, …)"),
/// once `device_from_name("wgpu")` has acquired it; `None` before, without one, or in a build
/// without the `wgpu` feature.
pub fn wgpu_adapter() -> Option<&'static str> {
    #[cfg(feature = "wgpu")]
    {
        wgpu::adapter()
    }
    #[cfg(not(feature = "wgpu"))]
    {
        None
    }
}

/// Whether `device` computes on the host CPU (flex, ndarray or LibTorch's CPU device).
pub fn is_cpu(device: &Device) -> bool {
    let plain = device.clone().without_autodiff();
    #[cfg(feature = "flex")]
    if plain == Device::flex() {
        return true;
    }
    #[cfg(feature = "ndarray")]
    #[allow(deprecated)]
    if plain == Device::ndarray() {
        return true;
    }
    #[cfg(feature = "tch")]
    #[allow(deprecated)]
    if plain == Device::libtorch() {
        return true;
    }
    false
}

/// Whether `device` is flex (with or without autodiff).
pub fn is_flex(device: &Device) -> bool {
    #[cfg(feature = "flex")]
    if device.clone().without_autodiff() == Device::flex() {
        return true;
    }
    let _ = device;
    false
}

pub fn compiled_backends() -> Vec<&'static str> {
    let mut v = Vec::new();
    if cfg!(feature = "flex") {
        v.push("flex");
    }
    if cfg!(feature = "ndarray") {
        v.push("ndarray");
    }
    if cfg!(feature = "tch") {
        v.push("tch");
    }
    if cfg!(feature = "wgpu") {
        v.push("wgpu");
    }
    if cfg!(feature = "cuda") {
        v.push("cuda");
    }
    v
}

/// Keep freed memory in the process heap instead of returning it to the OS. glibc hands every
/// block over its mmap threshold (at most 32 MiB, e.g. Network-1's 4×256×128² class map) back
/// to the OS on free, so each training step page-faults its large activations in again: a large
/// share of a CPU step went to the kernel clearing pages. Process-wide, so it is called
/// by the binary and the benches, never by library code. glibc still maps blocks over 64 MiB
/// that a thread other than the main one allocates (its per-thread heaps are that size). Returns
/// whether the setting took (false off glibc, where nothing is changed).
pub fn retain_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only changes allocator parameters; it is called before any thread
        // that allocates concurrently is started by us, and glibc serialises it anyway.
        unsafe {
            libc::mallopt(libc::M_MMAP_MAX, 0) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(all(test, feature = "flex"))]
mod tests {
    use super::*;
    use burn::tensor::Tensor;
    #[test]
    fn flex_computes() {
        let dev = device_from_name("flex").expect("flex device");
        let t = Tensor::<2>::from_floats([[1.0, 2.0], [3.0, 4.0]], &dev);
        let s: f32 = t.clone().matmul(t).sum().into_scalar();
        // [[7,10],[15,22]] sums to 54.
        assert_eq!(s, 54.0);
        assert!(device_from_name("tpu").is_err());
        // An index only means something for cuda; elsewhere it is refused, not ignored.
        let err = device_from_name("flex:1").expect_err("index").to_string();
        assert!(err.contains("only cuda takes an index"), "{err}");
    }
}

#[cfg(all(test, target_os = "linux", target_env = "gnu"))]
mod heap_tests {
    /// A 48 MiB block (over glibc's largest mmap threshold, under its 64 MiB per-thread heap:
    /// the test runs on a harness thread) must come from the heap once the setting is on:
    /// mallinfo2 counts no more mmapped blocks while it is alive than before it. "No more", not
    /// "as many": tests on other threads may free blocks they mapped before the setting took.
    #[test]
    fn large_blocks_stay_in_the_heap() {
        assert!(super::retain_freed_memory());
        // SAFETY: mallinfo2 only reads allocator statistics.
        let before = unsafe { libc::mallinfo2() }.hblks;
        // black_box: an allocation nothing reads may be optimised away.
        let block = std::hint::black_box(vec![1u8; 48 << 20]);
        // SAFETY: as above.
        let info = unsafe { libc::mallinfo2() };
        assert!(
            info.hblks <= before,
            "{} mmapped blocks, {before} before",
            info.hblks
        );
        assert!(info.arena + info.hblkhd >= block.len(), "block not counted");
        drop(block);
    }
}

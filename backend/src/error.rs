//! The one error type of the backend. Every variant names what went wrong and, where a person
//! can fix it, what to do (which package to install, which flag to change).
//!
//! A leaf: it also holds the errors that [`BackendError`] wraps (of the plan, of building a kernel plan, of
//! shaders), so every module reports through it without it importing any of them.

use ash::vk;
use parallax_graph::{AllocId, InstanceId};

/// Errors of the Vulkan backend.
#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    /// `libvulkan.so.1` could not be opened.
    #[error(
        "cannot load the Vulkan loader (libvulkan.so.1): {0}; install it with `apt-get install libvulkan1 mesa-vulkan-drivers`"
    )]
    LoaderMissing(String),

    /// The loader works but no driver exposes a physical device.
    #[error(
        "no Vulkan device found; install a driver: `apt-get install mesa-vulkan-drivers` (lavapipe, software) or the GPU vendor's driver"
    )]
    NoDevice,

    /// `--gpus N` asked for more physical devices than the machine has.
    #[error(
        "asked for {requested} GPUs but only {available} Vulkan device(s) exist; use --gpus {available} or --fake-devices {requested}"
    )]
    NotEnoughGpus { requested: usize, available: usize },

    /// Zero devices were asked for.
    #[error("the device count must be at least 1")]
    ZeroDevices,

    /// The Khronos validation layer was requested but is not installed.
    #[error(
        "PARALLAX_VALIDATION is set but VK_LAYER_KHRONOS_validation is not installed; `apt-get install vulkan-validationlayers`"
    )]
    ValidationLayerMissing,

    /// A device lacks an extension or feature the backend cannot work without.
    #[error("device {device} ({name}) lacks {what}, which the backend needs")]
    MissingCapability { device: usize, name: String, what: String },

    /// A Vulkan call failed.
    #[error("{call} failed: {result}")]
    Vk { call: &'static str, result: vk::Result },

    /// The driver reports the device lost (`VK_ERROR_DEVICE_LOST`): it reset the GPU, and
    /// nothing of the run can be trusted or finished.
    #[error(
        "the GPU was lost ({call}: VK_ERROR_DEVICE_LOST): the driver reset it, most likely because a queue waited \
         too long for a signal (the driver's watchdog) or a shader read or wrote out of bounds; rerun small with \
         PARALLAX_VALIDATION=1 to see which, and look for NVRM Xid lines in the kernel log (dmesg)"
    )]
    DeviceLost { call: &'static str },

    /// gpu-allocator could not allocate or free.
    // The source is not repeated here: `{:#}` prints the chain, and it would appear twice.
    #[error("memory allocation for {what} failed")]
    Allocation { what: String, source: gpu_allocator::AllocationError },

    /// No memory type can hold an imported host allocation on this device.
    #[error("device {device} cannot import host memory for a buffer ({detail})")]
    HostImport { device: usize, detail: String },

    /// The validation layer reported errors or warnings.
    #[error("Vulkan validation reported {} message(s); first: {}", .messages.len(), .messages.first().map(String::as_str).unwrap_or(""))]
    Validation { messages: Vec<String> },

    /// The plan handed to the executor is inconsistent.
    #[error("invalid execution plan: {0}")]
    ExecutionPlan(#[from] ExecutionPlanError),

    /// A graph the backend declares itself (the benchmarks') does not compile.
    #[error("cannot compile the graph: {0}")]
    Graph(#[from] parallax_graph::GraphError),

    /// The schedule cannot become a kernel plan.
    #[error("cannot build the kernel plan of the schedule: {0}")]
    KernelPlan(#[from] KernelPlanError),

    /// A kernel asked for a shader that no layer of its library (ExecOptions::shaders) nor the
    /// backend's own shaders have.
    #[error(
        "no shader named `{name}`: looked in {}; add it to ExecOptions::shaders with \
         ShaderLibrary::with_spirv or include_shaders!",
        searched_list(.searched)
    )]
    UnknownShader { name: String, searched: Vec<SearchedShaders> },

    /// Bytes or words handed over as a shader are not SPIR-V.
    #[error("shader `{shader}` is not SPIR-V: {defect}")]
    InvalidSpirv { shader: String, defect: SpirvDefect },

    /// A shader's push-constant block cannot be read from its SPIR-V.
    #[error("cannot read the push-constant block of shader `{shader}`: {defect}")]
    Reflection { shader: String, defect: crate::reflect::ReflectError },

    /// A kernel's push-constant struct does not match the block its shader declares (found
    /// when the pipeline is created and at every dispatch, before anything runs).
    #[error(
        "pass `{pass}` pushes `{rust_type}` to shader `{shader}`, whose push-constant block differs at `{field}`: \
         {problem}; make the #[repr(C)] struct and its push_constants! list match the GLSL block"
    )]
    PushConstantLayout { pass: String, shader: String, rust_type: &'static str, field: String, problem: String },

    /// A kernel's use of the instance does not match what the kernel expects (`instance`: the
    /// pass instance, where the call that refused it knows it).
    #[error("kernel `{kernel}` cannot record {}: {detail}", instance.map_or("its pass instance".into(), |i| format!("pass instance {i}")))]
    KernelMisuse { kernel: String, instance: Option<InstanceId>, detail: String },

    /// A kernel bound a slot token its pass instance does not have (one another pass's
    /// declaration returned).
    #[error(transparent)]
    UnboundSlot(#[from] parallax_graph::UnboundSlot),

    /// A kernel asked for a global buffer that was never uploaded.
    #[error("no global buffer `{name}` on device {device}; upload it with Executor::upload_buffer before running")]
    UnknownBuffer { name: String, device: usize },

    /// Texture bytes that do not match the texture's size.
    #[error("texture `{name}`: {width}x{height} RGBA8 needs width*height*4 bytes, got {bytes}")]
    TextureData { name: String, width: u32, height: u32, bytes: usize },

    /// More textures than the texture array of the descriptor layout holds.
    #[error("{count} textures exceed the backend's texture array of {max} (parallax_backend::MAX_TEXTURES)")]
    TooManyTextures { count: usize, max: u32 },

    /// Per-frame data larger than the executor's capacity.
    #[error("per-frame data of {bytes} bytes exceeds the capacity of {capacity} (ExecOptions::frame_data_bytes)")]
    FrameDataTooLarge { bytes: usize, capacity: u64 },

    /// `Recorder::dispatch_indirect` was pointed at something that cannot hold its arguments.
    #[error("indirect dispatch of `{shader}` from resource {resource} at byte {offset}: {problem}")]
    IndirectArgs { shader: String, resource: AllocId, offset: u64, problem: String },

    /// A kernel asked for a section of the per-frame data that the frame data does not have.
    #[error(
        "no per-frame data section `{name}` (sections: {known:?}); add it with FrameData::section and Executor::set_frame before the first frame"
    )]
    UnknownFrameSection { name: String, known: Vec<String> },

    /// Two sections of one `FrameData` with the same name.
    #[error("per-frame data section `{0}` is added twice")]
    DuplicateFrameSection(String),

    /// A kernel asked for the frame block of cameras, and the frame data has none.
    #[error(
        "pass `{pass}` reads the frame block of cameras, but the per-frame data has none; add it with FrameData::frame_block and Executor::set_frame before the first frame"
    )]
    NoFrameBlock { pass: String },

    /// `FrameData::frame_block` twice on one frame.
    #[error("the frame block is added twice to one frame's data")]
    DuplicateFrameBlock,

    /// `Executor::submit_frame` without `ExecOptions::read_back_exports`.
    #[error("submit_frame reads exported resources back, which needs ExecOptions::read_back_exports = true")]
    ReadbackDisabled,

    /// `Executor::wait_readback` for a frame whose readback is not there.
    #[error("no readback of frame {frame}: it was already taken, or the frame was not submitted with submit_frame")]
    ReadbackUnavailable { frame: u64 },

    /// A resource is not present on the device where it was asked for.
    #[error("resource {resource} is not allocated on device {device}")]
    ResourceNotOnDevice { resource: AllocId, device: usize },

    /// Device memory could not be shared between two logical devices of one GPU (link_memory.rs).
    #[error("device {device} cannot share staging memory with another device of its GPU ({detail})")]
    MemoryShare { device: usize, detail: String },

    /// A link kind was requested (`ExecOptions::link`) that a pair of devices cannot use.
    #[error("link kind `{kind}` is unavailable from device {from} to device {to}: {missing}")]
    LinkUnavailable { kind: &'static str, from: usize, to: usize, missing: String },

    /// A link to or from another process's device failed (crate::remote): the transport's
    /// message, which names the process.
    #[error("{0}")]
    Remote(String),

    /// A host relay thread (cross-device signal forwarding) failed.
    #[error("cross-device relay failed: {0}")]
    Relay(String),

    /// The fault-injection hook was asked for something it cannot do deterministically.
    #[error("fault injection not possible: {0}")]
    FaultInjection(String),

    /// A frame's submission failed part-way (a lost device, a timeout): its first segments are
    /// on the queues and its timeline values taken, so no later frame can be submitted.
    #[error("frame {frame}'s submission failed part-way; the executor cannot run further frames")]
    SubmissionCutShort { frame: u64 },

    /// A frame stopped making progress: a lost signal or a GPU hang.
    #[error(
        "frame {frame} did not complete on device {device}: no device made progress for {seconds} s (lost cross-device signal or GPU hang)"
    )]
    FrameTimeout { frame: u64, device: usize, seconds: u64 },

    /// Writing a report or trace file failed.
    #[error("cannot write {path}")]
    Io { path: String, source: std::io::Error },
}

/// `a, b, c`, or `none` for an empty list.
/// "origin (a, b), origin (none)" for an unknown shader's message.
fn searched_list(searched: &[SearchedShaders]) -> String {
    let places: Vec<String> = searched.iter().map(|s| format!("{} ({})", s.origin, list(&s.names))).collect();
    places.join(", then ")
}

fn list(names: &[String]) -> String {
    if names.is_empty() { "none".into() } else { names.join(", ") }
}

/// Shorthand used across the crate.
pub type Result<T> = std::result::Result<T, BackendError>;

/// Adds the name of the Vulkan call to an `ash` result.
pub(crate) trait VkContext<T> {
    fn vk(self, call: &'static str) -> Result<T>;
}

impl<T> VkContext<T> for std::result::Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T> {
        self.map_err(|result| BackendError::vk(call, result))
    }
}

impl BackendError {
    /// The error of a failed Vulkan call: [`BackendError::DeviceLost`] for a lost device,
    /// whichever call noticed it first.
    pub(crate) fn vk(call: &'static str, result: vk::Result) -> Self {
        match result {
            vk::Result::ERROR_DEVICE_LOST => BackendError::DeviceLost { call },
            result => BackendError::Vk { call, result },
        }
    }
}

/// What the executor refuses in a plan: the checks only the backend can make, and the form of the
/// barrier lists it records by. What a plan built from a schedule inherits from it (ids, rows,
/// op placement and order, barriers, copies, history pairs, exports on device 0) was proven once,
/// when the schedule was (`parallax_graph::ProvenSchedule`); a hand-laid plan is trusted with
/// those.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ExecutionPlanError {
    #[error("plan has {plan} device programs but the context has {context} devices")]
    DeviceCount { plan: usize, context: usize },
    #[error("pass instance {index} (`{pass}`) has no kernel in the plan: give its pass one")]
    MissingKernel { pass: String, index: InstanceId },
    #[error("resource {resource} is an image: only buffers can be reset each frame")]
    ResetOfImage { resource: AllocId },
    #[error(
        "resource {resource}: a reset header of {words} words is longer than its {capacity}-word buffer or than the {max} words vkCmdUpdateBuffer writes"
    )]
    ResetTooLong { resource: AllocId, words: usize, capacity: u32, max: usize },
    #[error("the devices' copy-ins wait for each other's copy-outs in a cycle: no order of submissions can run")]
    WaitCycle,
    #[error("{0}: place the barriers with ExecutionPlan::place_barriers")]
    Barriers(parallax_graph::ScheduleError),
}

/// What keeps a schedule from becoming a [`crate::KernelPlan`] (a pass without its kernel, a
/// device without its program).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum KernelPlanError {
    #[error("the schedule has programs for devices {found:?}; expected exactly 0..{expected}")]
    DevicePrograms { found: Vec<u32>, expected: usize },
    #[error("pass `{pass}` was declared without a kernel: attach one with `.kernel(...)` where it is declared")]
    MissingKernel { pass: String },
    #[error(
        "pass `{pass}`'s kernel records its instances in groups, but the pass was not declared `.grouped()`: declare it so where it is declared (its copy-outs then wait for the end of its runs)"
    )]
    UngroupedKernel { pass: String },
}

/// Why [`Compiled::compile`](crate::Compiled::compile) failed: the error of the step that
/// failed, shown as that error alone, so a caller reports it as it reported the step's own.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CompileError {
    #[error(transparent)]
    Graph(#[from] parallax_graph::GraphError),
    #[error(transparent)]
    KernelPlan(#[from] KernelPlanError),
}

/// Each step's error becomes the backend error it becomes alone ([`BackendError::Graph`],
/// [`BackendError::KernelPlan`]).
impl From<CompileError> for BackendError {
    fn from(error: CompileError) -> BackendError {
        match error {
            CompileError::Graph(e) => BackendError::Graph(e),
            CompileError::KernelPlan(e) => BackendError::KernelPlan(e),
        }
    }
}

/// Why bytes or words are not a SPIR-V module.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SpirvDefect {
    /// SPIR-V is a sequence of 32-bit words.
    #[error("{bytes} bytes is not a whole number of 32-bit words")]
    Unaligned { bytes: usize },
    /// Shorter than the 5-word header.
    #[error("{words} words is shorter than the 5-word SPIR-V header")]
    TooShort { words: usize },
    /// The first word is not the SPIR-V magic number 0x07230203 (in either byte order).
    #[error("first word {found:#010x} is not the SPIR-V magic number 0x07230203")]
    BadMagic { found: u32 },
}

/// One place [`ShaderLibrary::spirv`](crate::ShaderLibrary::spirv) looked for a shader, for
/// [`BackendError::UnknownShader`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SearchedShaders {
    /// Where the shaders come from: [`USER_SHADERS`](crate::USER_SHADERS), a crate's ("the
    /// shaders of" and its name, from [`crate::include_shaders!`]) or
    /// [`BACKEND_SHADERS`](crate::BACKEND_SHADERS).
    pub origin: String,
    /// The shader names found there, sorted.
    pub names: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lost_device_is_one_line_naming_the_call_and_the_likely_causes() {
        let lost = BackendError::vk("vkQueueSubmit2", vk::Result::ERROR_DEVICE_LOST);
        assert!(matches!(lost, BackendError::DeviceLost { call: "vkQueueSubmit2" }));
        let text = lost.to_string();
        assert_eq!(text.lines().count(), 1, "{text}");
        for needle in ["GPU was lost", "vkQueueSubmit2", "waited too long", "out of bounds", "PARALLAX_VALIDATION=1"] {
            assert!(text.contains(needle), "{needle} in {text}");
        }
        let other = BackendError::vk("vkQueueSubmit2", vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
        assert!(matches!(other, BackendError::Vk { .. }));
    }
}

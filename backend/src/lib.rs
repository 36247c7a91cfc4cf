//! parallax-backend: everything Vulkan (ash 0.38).
//!
//! * [`Context`]: instance (+ validation), N physical devices (`--gpus N`) or N logical
//!   devices on one physical device (`--fake-devices N`).
//! * [`Plan`]: what the executor runs, lowered from the graph crate's `Schedule`.
//! * [`Executor`]: records per-device command buffers once, submits frames with timeline
//!   semaphores, moves cross-device copies through host memory imported into both devices, and
//!   times every pass instance and copy ([`FrameReport`], [`chrome_trace`]).
//! * [`PassKernel`] / [`KernelRegistry`]: how passes plug their GPU work in.

mod context;
mod device;
mod error;
mod executor;
mod instance;
mod lower;
mod memory;
mod pipeline;
mod record;
mod recorder;
mod relay;
mod segments;
mod timing;

pub mod bench;
pub mod demo;
pub mod kernels;
pub mod plan;

pub use context::{Context, ContextDesc, DeviceSelection};
pub use device::{CalibrationMethod, ClockCalibration, Device, DeviceInfo, host_now_ns};
pub use error::{BackendError, Result};
pub use executor::{ExecOptions, Executor, FaultInjection};
pub use instance::{Instance, Validation, validation_from_env};
pub use lower::LowerError;
pub use memory::{Buffer, Image, SharedHostBuffer};
pub use pipeline::{shader_names, spirv};
pub use plan::{Plan, PlanAccess, PlanCopy, PlanError, PlanOp, PlanPass, PlanResource, Rows, TexelFormat};
pub use recorder::{KernelRegistry, PassKernel, PassParams, Recorder};
pub use segments::{Chunk, chunks_of_copies};
pub use timing::{DeviceFrameStats, EventKind, FrameReport, StageStats, TimedEvent, chrome_trace, write_json};

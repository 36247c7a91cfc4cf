//! The recording API that pass kernels see, and the registry that maps pass names to kernels.
//!
//! A kernel never touches descriptors, barriers or timestamps: the executor binds the device's
//! descriptor set, puts a barrier before each op and a timestamp pair around it. The kernel only
//! chooses a shader, fills [`PassParams`] from the pass instance and dispatches.

use std::collections::HashMap;
use std::sync::Arc;

use ash::vk;

use crate::error::{BackendError, Result};
use crate::pipeline::{Bindless, PUSH_CONSTANT_BYTES};
use crate::plan::{Plan, PlanPass, PlanResource};

/// Push constants of every kernel (`PassParams` in shaders/include/bindless.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PassParams {
    pub dst: u32,
    pub src0: u32,
    pub src1: u32,
    pub view: u32,
    pub y0: u32,
    pub y1: u32,
    pub width: u32,
    pub param: u32,
}

impl PassParams {
    fn to_bytes(self) -> [u8; PUSH_CONSTANT_BYTES as usize] {
        let words = [self.dst, self.src0, self.src1, self.view, self.y0, self.y1, self.width, self.param];
        let mut bytes = [0u8; PUSH_CONSTANT_BYTES as usize];
        for (chunk, w) in bytes.chunks_exact_mut(4).zip(words) {
            chunk.copy_from_slice(&w.to_le_bytes());
        }
        bytes
    }
}

/// Records the work of one pass instance into a device's command buffer.
pub struct Recorder<'a> {
    pub(crate) raw: &'a ash::Device,
    pub(crate) cb: vk::CommandBuffer,
    pub(crate) bindless: &'a mut Bindless,
    pub(crate) image_slots: &'a HashMap<usize, u32>,
    pub(crate) plan: &'a Plan,
    pub(crate) device_index: usize,
    pub(crate) bound: Option<vk::Pipeline>,
}

impl Recorder<'_> {
    /// Index of `resource` in the device's image array (what shaders get in push constants).
    pub fn image(&self, resource: usize) -> Result<u32> {
        self.image_slots
            .get(&resource)
            .copied()
            .ok_or(BackendError::ResourceNotOnDevice { resource, device: self.device_index })
    }

    /// The plan's description of `resource`.
    pub fn resource(&self, resource: usize) -> &PlanResource {
        &self.plan.resources[resource]
    }

    /// Index of the device being recorded.
    pub fn device_index(&self) -> usize {
        self.device_index
    }

    /// Binds the embedded compute shader `shader`, pushes `params` and dispatches `groups`.
    pub fn dispatch(&mut self, shader: &str, params: PassParams, groups: [u32; 3]) -> Result<()> {
        let pipeline = self.bindless.pipeline(shader)?;
        unsafe {
            if self.bound != Some(pipeline) {
                self.raw.cmd_bind_pipeline(self.cb, vk::PipelineBindPoint::COMPUTE, pipeline);
                self.bound = Some(pipeline);
            }
            self.raw.cmd_push_constants(
                self.cb,
                self.bindless.pipeline_layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                &params.to_bytes(),
            );
            self.raw.cmd_dispatch(self.cb, groups[0], groups[1], groups[2]);
        }
        Ok(())
    }

    /// Dispatches `shader` over `params.width` × rows `[y0, y1)` with the 8×8 workgroups every
    /// row-band kernel in shaders/ uses.
    pub fn dispatch_rows(&mut self, shader: &str, params: PassParams) -> Result<()> {
        let rows = params.y1.saturating_sub(params.y0);
        self.dispatch(shader, params, [params.width.div_ceil(8), rows.div_ceil(8), 1])
    }

    /// The raw command buffer, for kernels that need a command the recorder does not wrap.
    pub fn command_buffer(&self) -> vk::CommandBuffer {
        self.cb
    }

    /// The raw device, with [`Self::command_buffer`].
    pub fn raw_device(&self) -> &ash::Device {
        self.raw
    }
}

/// The GPU work of one pass (by name). Implemented by the passes crate for path tracing,
/// reprojection, denoising, ...; the backend ships the small kernels its own tests use.
pub trait PassKernel: Send + Sync {
    /// Records instance `index` of the plan (`pass` = `plan.passes[index]`).
    fn record(&self, rec: &mut Recorder<'_>, pass: &PlanPass, index: usize) -> Result<()>;
}

/// Pass name → kernel.
#[derive(Clone, Default)]
pub struct KernelRegistry {
    kernels: HashMap<String, Arc<dyn PassKernel>>,
}

impl KernelRegistry {
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers `kernel` for pass `name` (replacing an earlier one).
    pub fn register(&mut self, name: impl Into<String>, kernel: impl PassKernel + 'static) {
        self.kernels.insert(name.into(), Arc::new(kernel));
    }

    /// Builder form of [`Self::register`].
    pub fn with(mut self, name: impl Into<String>, kernel: impl PassKernel + 'static) -> Self {
        self.register(name, kernel);
        self
    }

    /// The kernel of pass `name`.
    pub fn get(&self, name: &str) -> Result<&Arc<dyn PassKernel>> {
        self.kernels.get(name).ok_or_else(|| {
            let mut registered: Vec<String> = self.kernels.keys().cloned().collect();
            registered.sort();
            BackendError::UnknownPass { pass: name.to_string(), registered }
        })
    }

    /// Fails with [`BackendError::UnknownPass`] for the first pass of `plan` without a kernel.
    pub fn check_plan(&self, plan: &Plan) -> Result<()> {
        plan.passes.iter().try_for_each(|p| self.get(&p.name).map(|_| ()))
    }
}

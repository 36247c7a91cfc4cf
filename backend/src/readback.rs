//! The frame loop's readback ([`crate::Executor::submit_frame`]): device 0's last submission of
//! every frame copies the plan's exported resources into host-visible buffers of the frame's
//! slot (recorded once, like everything else); when the frame retires, the bytes move to host
//! memory, where [`crate::Executor::wait_readback`] picks them up. Nothing waits for more than
//! the frame asked for, and no frame needs a `finish()`.

use std::collections::HashMap;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::device::Device;
use crate::error::Result;
use crate::memory::Buffer;
use crate::plan::{AllocId, ExecResource, ExecutionPlan};

/// A submitted frame whose exported resources can be waited for, once.
#[derive(Debug, PartialEq, Eq)]
#[must_use = "the frame's readback stays in host memory until wait_readback takes it"]
pub struct FrameTicket {
    pub(crate) frame: u64,
}

impl FrameTicket {
    /// Index of the frame (as `Executor::run_frame` returns it).
    pub fn frame(&self) -> u64 {
        self.frame
    }
}

/// The exported resources of one frame: `(resource, bytes)` in resource order; images as
/// tightly packed rows (as `Executor::read_resource`), buffers whole.
pub type FrameReadback = Vec<(AllocId, Vec<u8>)>;

pub(crate) struct Readback {
    /// Per frame-in-flight slot: each exported resource and its buffer on device 0.
    slots: Vec<Vec<(AllocId, Buffer)>>,
    /// Bytes of retired frames, by frame, until their ticket takes them.
    retired: HashMap<u64, FrameReadback>,
}

impl Readback {
    pub(crate) fn new() -> Self {
        Self { slots: Vec::new(), retired: HashMap::new() }
    }

    /// Buffers for `plan`'s exports in each of `slots` slots, replacing the previous plan's (no
    /// frame may be in flight). Bytes of retired frames stay.
    pub(crate) fn allocate(&mut self, device0: &Arc<Device>, plan: &ExecutionPlan, slots: usize) -> Result<()> {
        let exported: Vec<(AllocId, &ExecResource)> = plan.resource_ids().filter(|(_, r)| r.exported).collect();
        self.slots = (0..slots)
            .map(|_| {
                exported
                    .iter()
                    .map(|&(r, desc)| {
                        let name = format!("readback of {} view {}", desc.name, desc.view);
                        let buffer = Buffer::new(
                            device0,
                            &name,
                            desc.bytes(),
                            vk::BufferUsageFlags::TRANSFER_DST,
                            MemoryLocation::GpuToCpu,
                        )?;
                        Ok((r, buffer))
                    })
                    .collect::<Result<Vec<_>>>()
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(())
    }

    /// What device 0's last segment of `slot` copies into.
    pub(crate) fn targets(&self, slot: usize) -> Vec<(AllocId, vk::Buffer)> {
        self.slots.get(slot).map_or_else(Vec::new, |s| s.iter().map(|(r, b)| (*r, b.raw)).collect())
    }

    /// Moves the bytes of `frame` (just retired, in `slot`) to host memory before the slot is
    /// reused.
    pub(crate) fn retire(&mut self, frame: u64, slot: usize) {
        let bytes = self.slots[slot]
            .iter()
            .map(|(r, b)| (*r, b.mapped().expect("GpuToCpu buffers are mapped").to_vec()))
            .collect();
        self.retired.insert(frame, bytes);
    }

    /// The bytes of retired `frame`, removed.
    pub(crate) fn take(&mut self, frame: u64) -> Option<FrameReadback> {
        self.retired.remove(&frame)
    }
}

//! Recording every frame slot's command buffers (once per plan, or after a global buffer, the
//! textures or the frame data layout changed).

use std::collections::HashMap;
use std::time::Instant;

use crate::error::Result;
use crate::plan::AllocId;
use crate::record::{SegmentContext, SegmentPlace, SegmentScratch, record_segment};

use super::Executor;

impl Executor {
    pub(super) fn record_all(&mut self) -> Result<()> {
        let started = Instant::now();
        let plan = &self.plan;
        let parity_maps = [plan.parity_map(0), plan.parity_map(1)];
        let addresses: Vec<HashMap<String, (u64, u64)>> = self
            .globals
            .iter()
            .map(|g| g.iter().map(|(name, b)| (name.clone(), (b.device_address(), b.size))).collect())
            .collect();
        for (d, state) in self.states.iter_mut().enumerate() {
            let buffer_addresses: HashMap<AllocId, u64> =
                state.buffers.iter().map(|(&r, b)| (r, b.device_address())).collect();
            for slot in 0..state.slots.len() {
                // Recording happens with no frame in flight (every cause of it waits for the
                // frames first), so the buffers of the last recording are free.
                state.recording_buffers[slot].clear();
                let readback = match &self.readback {
                    Some(readback) if d == 0 => readback.targets(slot),
                    _ => Vec::new(),
                };
                let staging = self.staging.as_ref().map(|s| s.of_device(d, slot)).unwrap_or_default();
                let ctx = SegmentContext {
                    barriers: self.options.barriers,
                    raw: &state.device.raw,
                    device_index: d,
                    plan,
                    parity_map: &parity_maps[slot % 2],
                    images: &state.images,
                    image_slots: &state.image_slots,
                    slot,
                    query_pool: state.slots[slot].query_pool,
                    staging: &staging,
                    global_buffers: &addresses[d],
                    buffers: &state.buffers,
                    buffer_addresses: &buffer_addresses,
                    frame_data_address: self.frame_data_buffers[slot][d].device_address(),
                    frame_sections: self.frame_data.sections(),
                    frame_block: self.frame_data.frame_block_offset(),
                    readback: &readback,
                    device: &state.device,
                };
                let mut scratch = SegmentScratch {
                    bindless: &mut state.bindless,
                    recording_buffers: &mut state.recording_buffers[slot],
                };
                let mut first_timer = 0u32;
                let segment_count = state.segments.len();
                for (j, segment) in state.segments.iter().enumerate() {
                    let cb = state.slots[slot].command_buffers[j];
                    let place = SegmentPlace { first: j == 0, last: j + 1 == segment_count };
                    let spans = &state.timer_spans[j];
                    record_segment(&ctx, &mut scratch, cb, segment, first_timer, spans, place)?;
                    first_timer += spans.len() as u32;
                }
            }
        }
        self.recordings += 1;
        self.last_record_ns = started.elapsed().as_nanos() as u64;
        self.needs_record = false;
        Ok(())
    }
}

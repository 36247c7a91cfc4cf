//! The execution plan: the part of a compiled `Schedule` the executor needs, as plain data with
//! indices resolved. It mirrors the graph crate's op lists one to one (pass, copy-out, signal,
//! wait, copy-in per device, in submission order), so lowering a `Schedule` is a field-by-field
//! translation, and the executor can be tested with hand-written plans.

use std::collections::HashMap;

/// A row band `[y0, y1)` of a view image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct Rows {
    pub y0: u32,
    pub y1: u32,
}

impl Rows {
    pub fn new(y0: u32, y1: u32) -> Self {
        Self { y0, y1 }
    }
    pub fn len(self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }
    pub fn is_empty(self) -> bool {
        self.len() == 0
    }
}

/// Texel formats of plan resources.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum TexelFormat {
    Rgba32Float,
    Rgba16Float,
    Rg32Float,
    R32Float,
    Rgba8Unorm,
    R32Uint,
}

impl TexelFormat {
    pub fn bytes_per_texel(self) -> u32 {
        match self {
            Self::Rgba32Float => 16,
            Self::Rgba16Float | Self::Rg32Float => 8,
            Self::R32Float | Self::Rgba8Unorm | Self::R32Uint => 4,
        }
    }
}

/// What a plan resource is on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum ResourceKind {
    /// A 2D storage image of `width`×`height` texels of `format`.
    Image,
    /// A storage buffer, described as one row (`height` 1) of `width` 32-bit words
    /// (`format` [`TexelFormat::R32Uint`]), so copies and validation treat both kinds alike.
    /// Shaders reach it by address ([`crate::Recorder::buffer_of`]).
    Buffer,
}

/// One per-view resource.
#[derive(Clone, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct PlanResource {
    pub name: String,
    pub view: u32,
    pub width: u32,
    pub height: u32,
    pub format: TexelFormat,
    pub kind: ResourceKind,
    /// A finished output, gathered on device 0 (the graph's `export`): what the frame loop
    /// reads back ([`crate::Executor::submit_frame`]).
    pub exported: bool,
    /// Buffers only: rewritten on the GPU at the start of every frame, before any pass of the
    /// frame touches it, on every device that holds it: the first `reset.len()` words set to
    /// these, the rest zeroed (`Some(vec![])` zeroes it all). For counters and indirect
    /// arguments that passes of the frame accumulate into.
    pub reset: Option<Vec<u32>>,
}

impl PlanResource {
    /// A per-view buffer of at least `bytes` bytes (rounded up to whole 32-bit words).
    pub fn buffer(name: impl Into<String>, view: u32, bytes: u64) -> Self {
        let words = bytes.div_ceil(4).clamp(1, u64::from(u32::MAX)) as u32;
        Self {
            name: name.into(),
            view,
            width: words,
            height: 1,
            format: TexelFormat::R32Uint,
            kind: ResourceKind::Buffer,
            exported: false,
            reset: None,
        }
    }

    /// Bytes of the whole resource.
    pub fn bytes(&self) -> u64 {
        self.row_bytes() * u64::from(self.height)
    }

    pub fn row_bytes(&self) -> u64 {
        u64::from(self.width) * u64::from(self.format.bytes_per_texel())
    }
}

/// One access of a pass instance to a resource version, over a row band.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct PlanAccess {
    pub resource: usize,
    pub version: u32,
    pub rows: Rows,
}

/// One pass instance: a pass of the graph run for one view (or a row band of it) on one device.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PlanPass {
    /// Pass name; selects the kernel.
    pub name: String,
    pub view: u32,
    pub rows: Rows,
    pub device: usize,
    /// Reads in the order the pass declared them (kernels rely on that order).
    pub reads: Vec<PlanAccess>,
    pub writes: Vec<PlanAccess>,
    /// Reads of the previous frame's last version (the image persists across frames).
    pub history_reads: Vec<PlanAccess>,
}

/// A transfer of a row band of one resource from one device to another.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct PlanCopy {
    pub resource: usize,
    pub version: u32,
    pub rows: Rows,
    pub from: usize,
    pub to: usize,
}

/// One step of a device program.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum PlanOp {
    /// Run pass instance `i`.
    Pass(usize),
    /// Producer side of copy `c`: device → shared host buffer.
    CopyOut(usize),
    /// Producer announces that copy `c` is in the host buffer.
    Signal(usize),
    /// Consumer waits for the producer's signal of copy `c`.
    Wait(usize),
    /// Consumer side of copy `c`: shared host buffer → device.
    CopyIn(usize),
}

/// A whole frame: resources, pass instances, copies and one op list per device.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Plan {
    pub resources: Vec<PlanResource>,
    pub passes: Vec<PlanPass>,
    pub copies: Vec<PlanCopy>,
    /// `devices[d]` is device d's op list in submission order.
    pub devices: Vec<Vec<PlanOp>>,
}

/// What can be inconsistent in a plan. The graph's `Schedule::validate()` checks the planning
/// invariants; these are the ones the executor depends on to not deadlock or read garbage.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PlanError {
    #[error("plan has {plan} device programs but the context has {context} devices")]
    DeviceCount { plan: usize, context: usize },
    #[error("{what} {index} refers to missing {missing} {target}")]
    Dangling { what: &'static str, index: usize, missing: &'static str, target: usize },
    #[error("{what} {index}: rows {y0}..{y1} are outside its {height}-row resource {resource}")]
    RowsOutOfRange { what: &'static str, index: usize, resource: usize, y0: u32, y1: u32, height: u32 },
    #[error("pass instance {pass} is in the program of device {listed} but belongs to device {owner}")]
    PassOnWrongDevice { pass: usize, listed: usize, owner: usize },
    #[error("pass instance {0} is not scheduled exactly once")]
    PassNotScheduledOnce(usize),
    #[error("copy {copy} goes from device {from} to itself")]
    CopyToSelf { copy: usize, from: usize },
    #[error("copy {copy}: {op:?} is missing, duplicated or on the wrong device")]
    CopyOpMisplaced { copy: usize, op: &'static str },
    #[error("copy {copy}: producer ops must be CopyOut then Signal, consumer ops Wait then CopyIn")]
    CopyOpOrder { copy: usize },
    #[error("resource {resource} has zero size")]
    EmptyResource { resource: usize },
    #[error("resource {resource} is an image: only buffers can be reset each frame")]
    ResetOfImage { resource: usize },
    #[error(
        "resource {resource}: a reset header of {words} words is longer than its {capacity}-word buffer or than the {max} words vkCmdUpdateBuffer writes"
    )]
    ResetTooLong { resource: usize, words: usize, capacity: u32, max: usize },
    #[error("resource {resource} is exported but device 0 never holds it: exports are gathered on device 0")]
    ExportNotOnDevice0 { resource: usize },
}

/// Most words a reset header may have: vkCmdUpdateBuffer writes at most 65536 bytes.
pub const MAX_RESET_WORDS: usize = 65536 / 4;

impl Plan {
    /// One pass instance `name` on device 0 writing all of `resource` (version 1) and nothing
    /// else; the other `devices - 1` devices stay idle. What a kernel that runs alone needs.
    pub fn single_pass(name: impl Into<String>, resource: PlanResource, devices: usize) -> Self {
        let all = Rows::new(0, resource.height);
        Plan {
            passes: vec![PlanPass {
                name: name.into(),
                view: resource.view,
                rows: all,
                device: 0,
                reads: vec![],
                writes: vec![PlanAccess { resource: 0, version: 1, rows: all }],
                history_reads: vec![],
            }],
            resources: vec![resource],
            copies: vec![],
            devices: (0..devices.max(1)).map(|d| if d == 0 { vec![PlanOp::Pass(0)] } else { vec![] }).collect(),
        }
    }

    /// Checks the invariants the executor relies on.
    pub fn validate(&self, context_devices: usize) -> Result<(), PlanError> {
        if self.devices.len() != context_devices {
            return Err(PlanError::DeviceCount { plan: self.devices.len(), context: context_devices });
        }
        for (i, r) in self.resources.iter().enumerate() {
            if r.width == 0 || r.height == 0 {
                return Err(PlanError::EmptyResource { resource: i });
            }
            if let Some(header) = &r.reset {
                if r.kind != ResourceKind::Buffer {
                    return Err(PlanError::ResetOfImage { resource: i });
                }
                if header.len() > r.width as usize || header.len() > MAX_RESET_WORDS {
                    return Err(PlanError::ResetTooLong {
                        resource: i,
                        words: header.len(),
                        capacity: r.width,
                        max: MAX_RESET_WORDS,
                    });
                }
            }
        }
        let check_rows = |what, index, resource: usize, rows: Rows| {
            let res = self.resources.get(resource).ok_or(PlanError::Dangling {
                what,
                index,
                missing: "resource",
                target: resource,
            })?;
            if rows.y0 >= rows.y1 || rows.y1 > res.height {
                return Err(PlanError::RowsOutOfRange {
                    what,
                    index,
                    resource,
                    y0: rows.y0,
                    y1: rows.y1,
                    height: res.height,
                });
            }
            Ok(())
        };
        for (i, p) in self.passes.iter().enumerate() {
            if p.device >= self.devices.len() {
                return Err(PlanError::Dangling {
                    what: "pass instance",
                    index: i,
                    missing: "device",
                    target: p.device,
                });
            }
            for a in p.reads.iter().chain(&p.writes).chain(&p.history_reads) {
                check_rows("pass instance", i, a.resource, a.rows)?;
            }
        }
        for (i, c) in self.copies.iter().enumerate() {
            check_rows("copy", i, c.resource, c.rows)?;
            for d in [c.from, c.to] {
                if d >= self.devices.len() {
                    return Err(PlanError::Dangling { what: "copy", index: i, missing: "device", target: d });
                }
            }
            if c.from == c.to {
                return Err(PlanError::CopyToSelf { copy: i, from: c.from });
            }
        }

        let mut pass_seen = vec![0usize; self.passes.len()];
        // Position of each copy op: (device, index in that device's list).
        let mut copy_ops: HashMap<(usize, &'static str), Vec<(usize, usize)>> = HashMap::new();
        for (d, ops) in self.devices.iter().enumerate() {
            for (pos, op) in ops.iter().enumerate() {
                let (copy, kind) = match *op {
                    PlanOp::Pass(p) => {
                        let pass = self.passes.get(p).ok_or(PlanError::Dangling {
                            what: "op of device",
                            index: d,
                            missing: "pass instance",
                            target: p,
                        })?;
                        if pass.device != d {
                            return Err(PlanError::PassOnWrongDevice { pass: p, listed: d, owner: pass.device });
                        }
                        pass_seen[p] += 1;
                        continue;
                    }
                    PlanOp::CopyOut(c) => (c, "CopyOut"),
                    PlanOp::Signal(c) => (c, "Signal"),
                    PlanOp::Wait(c) => (c, "Wait"),
                    PlanOp::CopyIn(c) => (c, "CopyIn"),
                };
                if copy >= self.copies.len() {
                    return Err(PlanError::Dangling { what: "op of device", index: d, missing: "copy", target: copy });
                }
                copy_ops.entry((copy, kind)).or_default().push((d, pos));
            }
        }
        if let Some(p) = pass_seen.iter().position(|&n| n != 1) {
            return Err(PlanError::PassNotScheduledOnce(p));
        }
        // Every op index is valid by now, and a context has at least one device.
        if !self.devices.is_empty() {
            let on_device0 = self.resources_of_device(0);
            let missing = self.resources.iter().enumerate().find(|(r, res)| res.exported && !on_device0.contains(r));
            if let Some((r, _)) = missing {
                return Err(PlanError::ExportNotOnDevice0 { resource: r });
            }
        }
        for (c, copy) in self.copies.iter().enumerate() {
            let at = |kind: &'static str, device: usize| match copy_ops.get(&(c, kind)).map(Vec::as_slice) {
                Some(&[(d, pos)]) if d == device => Ok(pos),
                _ => Err(PlanError::CopyOpMisplaced { copy: c, op: kind }),
            };
            let out = at("CopyOut", copy.from)?;
            let signal = at("Signal", copy.from)?;
            let wait = at("Wait", copy.to)?;
            let copy_in = at("CopyIn", copy.to)?;
            if out > signal || wait > copy_in {
                return Err(PlanError::CopyOpOrder { copy: c });
            }
        }
        Ok(())
    }

    /// Resources each device touches (reads, writes, copies in or out), sorted.
    pub fn resources_of_device(&self, device: usize) -> Vec<usize> {
        let mut used: Vec<usize> = Vec::new();
        for op in &self.devices[device] {
            match *op {
                PlanOp::Pass(p) => {
                    let pass = &self.passes[p];
                    used.extend(pass.reads.iter().chain(&pass.writes).chain(&pass.history_reads).map(|a| a.resource));
                }
                PlanOp::CopyOut(c) | PlanOp::CopyIn(c) => used.push(self.copies[c].resource),
                PlanOp::Signal(_) | PlanOp::Wait(_) => {}
            }
        }
        used.sort_unstable();
        used.dedup();
        used
    }

    /// Bytes moved by copy `c` (only the copied rows).
    pub fn copy_bytes(&self, c: usize) -> u64 {
        let copy = &self.copies[c];
        self.resources[copy.resource].row_bytes() * u64::from(copy.rows.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demo::{copy_benchmark, reprojection_demo};

    #[test]
    fn signal_before_copy_out_is_refused() {
        let mut plan = copy_benchmark(8, 8);
        plan.devices[0] = vec![PlanOp::Pass(0), PlanOp::Signal(0), PlanOp::CopyOut(0)];
        assert_eq!(plan.validate(2), Err(PlanError::CopyOpOrder { copy: 0 }));
    }

    #[test]
    fn pass_listed_on_another_device_is_refused() {
        let mut plan = copy_benchmark(8, 8);
        plan.devices[1].insert(0, PlanOp::Pass(0));
        assert_eq!(plan.validate(2), Err(PlanError::PassOnWrongDevice { pass: 0, listed: 1, owner: 0 }));
    }

    #[test]
    fn rows_outside_the_image_are_refused() {
        let mut plan = copy_benchmark(8, 8);
        plan.copies[0].rows = Rows::new(4, 9);
        assert_eq!(
            plan.validate(2),
            Err(PlanError::RowsOutOfRange { what: "copy", index: 0, resource: 0, y0: 4, y1: 9, height: 8 })
        );
    }

    #[test]
    fn copy_to_self_and_unscheduled_pass_are_refused() {
        let mut plan = copy_benchmark(8, 8);
        plan.copies[0].to = 0;
        assert_eq!(plan.validate(2), Err(PlanError::CopyToSelf { copy: 0, from: 0 }));
        let (mut plan, _) = reprojection_demo(2, 1, 8, 8);
        plan.devices[0].retain(|op| *op != PlanOp::Pass(1));
        assert_eq!(plan.validate(1), Err(PlanError::PassNotScheduledOnce(1)));
    }

    #[test]
    fn exports_must_reach_device_0_and_reset_headers_fit_their_buffer() {
        let mut plan = Plan::single_pass("fill_buffer", PlanResource::buffer("counts", 0, 8), 2);
        plan.resources[0].reset = Some(vec![0, 1]);
        plan.resources[0].exported = true;
        assert_eq!(plan.validate(2), Ok(()));
        plan.resources[0].reset = Some(vec![0, 1, 1]);
        assert_eq!(
            plan.validate(2),
            Err(PlanError::ResetTooLong { resource: 0, words: 3, capacity: 2, max: MAX_RESET_WORDS })
        );
        plan.resources[0].reset = None;
        plan.passes[0].device = 1;
        plan.devices = vec![vec![], vec![PlanOp::Pass(0)]];
        assert_eq!(plan.validate(2), Err(PlanError::ExportNotOnDevice0 { resource: 0 }));
    }

    #[test]
    fn copy_bytes_counts_only_the_band() {
        let mut plan = copy_benchmark(8, 8);
        plan.copies[0].rows = Rows::new(2, 5);
        assert_eq!(plan.copy_bytes(0), 8 * 16 * 3);
        assert_eq!(plan.resources_of_device(1), vec![0]);
    }
}

//! Lowering a compiled `parallax_graph::Schedule` to the executor's [`Plan`]: ids become
//! indices, regions become row bands, device programs are ordered by device id. Nothing is
//! re-planned here; the schedule's op order is kept exactly.

use parallax_graph::{Access, Format, Op, ResourceDesc, Schedule};

use crate::plan::{Plan, PlanAccess, PlanCopy, PlanOp, PlanPass, PlanResource, ResourceKind, Rows, TexelFormat};

/// What makes a schedule impossible to lower.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LowerError {
    #[error("the schedule has programs for devices {found:?}; expected exactly 0..{expected}")]
    DevicePrograms { found: Vec<u32>, expected: usize },
}

fn texel_format(format: Format) -> TexelFormat {
    match format {
        Format::Rgba32f => TexelFormat::Rgba32Float,
        Format::Rgba16f => TexelFormat::Rgba16Float,
        Format::Rg32f => TexelFormat::Rg32Float,
        Format::R32f => TexelFormat::R32Float,
        Format::R32u => TexelFormat::R32Uint,
        Format::Rgba8 => TexelFormat::Rgba8Unorm,
    }
}

fn access(a: &Access) -> PlanAccess {
    PlanAccess { resource: a.resource.index(), version: a.version, rows: Rows::new(a.region.y0, a.region.y1) }
}

impl Plan {
    /// Lowers `schedule`. Run `Plan::validate` (the executor does) for the execution invariants.
    pub fn from_schedule(schedule: &Schedule) -> Result<Plan, LowerError> {
        let resources = schedule
            .resources
            .iter()
            .map(|r| {
                let resource = match r.desc {
                    ResourceDesc::Image { width, height, format } => PlanResource {
                        name: r.name.clone(),
                        view: r.view.0,
                        width,
                        height,
                        format: texel_format(format),
                        kind: ResourceKind::Image,
                        exported: false,
                        reset: None,
                    },
                    ResourceDesc::Buffer { bytes } => PlanResource::buffer(r.name.clone(), r.view.0, bytes),
                };
                PlanResource { exported: r.exported.is_some(), ..resource }
            })
            .collect::<Vec<_>>();
        let passes = schedule
            .instances
            .iter()
            .map(|p| PlanPass {
                name: p.name.clone(),
                view: p.view.0,
                rows: Rows::new(p.region.y0, p.region.y1),
                device: p.device.index(),
                reads: p.reads.iter().map(access).collect(),
                writes: p.writes.iter().map(access).collect(),
                history_reads: p.history_reads.iter().map(access).collect(),
            })
            .collect();
        let copies = schedule
            .copies
            .iter()
            .map(|c| PlanCopy {
                resource: c.resource.index(),
                version: c.version,
                rows: Rows::new(c.region.y0, c.region.y1),
                from: c.from.index(),
                to: c.to.index(),
            })
            .collect();
        let mut programs: Vec<_> = schedule.devices.iter().collect();
        programs.sort_by_key(|p| p.device);
        let ids: Vec<u32> = programs.iter().map(|p| p.device.0).collect();
        if ids.iter().enumerate().any(|(i, &d)| d as usize != i) {
            return Err(LowerError::DevicePrograms { found: ids, expected: programs.len() });
        }
        let devices = programs
            .iter()
            .map(|p| {
                p.ops
                    .iter()
                    .map(|op| match *op {
                        Op::Pass(i) => PlanOp::Pass(i.index()),
                        Op::CopyOut(c) => PlanOp::CopyOut(c.index()),
                        Op::Signal(c) => PlanOp::Signal(c.index()),
                        Op::Wait(c) => PlanOp::Wait(c.index()),
                        Op::CopyIn(c) => PlanOp::CopyIn(c.index()),
                    })
                    .collect()
            })
            .collect();
        Ok(Plan { resources, passes, copies, devices })
    }
}

//! The storage and shape rules of `Schedule::validate()`: ids that point nowhere, accesses whose
//! allocation is not where they run, writes that share an allocation with a read without saying
//! so, write-after-read and write-after-write hazards on an allocation, row bands that do not
//! tile a view, empty resources and rows outside a resource (history pairs: validate_history.rs).
//!
//! Within a device every op is ordered (the executor puts a barrier before each op and chains
//! its queues), so a hazard is an op order in which an allocation is touched at an older
//! version after a newer one was written there.

use std::collections::HashMap;

use crate::error::ScheduleError;
use crate::ids::{AllocId, CopyId, InstanceId, PassId, Region, ResourceId, ViewId};
use crate::schedule::{Access, Op, ResourceDesc, Schedule};

/// (allocation, version, rows) an op reads or writes.
type Touches = Vec<(AllocId, u32, Region)>;

impl Schedule {
    /// Every id an op, instance, access or copy names exists.
    pub(crate) fn dangling_ids(&self) -> Vec<ScheduleError> {
        let mut errors = Vec::new();
        let mut dangling = |what, index: usize, missing, target: u32| {
            errors.push(ScheduleError::Dangling { what, index: index as u32, missing, target })
        };
        for program in &self.devices {
            for op in &program.ops {
                match *op {
                    Op::Pass(i) if i.index() >= self.instances.len() => dangling("op", 0, "instance", i.0),
                    Op::CopyOut(c) | Op::Signal(c) | Op::Wait(c) | Op::CopyIn(c) if c.index() >= self.copies.len() => {
                        dangling("op", 0, "copy", c.0)
                    }
                    _ => {}
                }
            }
        }
        let accesses_ok =
            |a: &Access| a.resource.index() < self.resources.len() && a.alloc.index() < self.allocations.len();
        for (i, inst) in self.instances.iter().enumerate() {
            if inst.pass.index() >= self.passes.len() {
                dangling("instance", i, "pass", inst.pass.0);
            }
            if inst.device.index() >= self.devices.len() {
                dangling("instance", i, "device", inst.device.0);
            }
            for a in inst.reads.iter().chain(&inst.writes).chain(&inst.history_reads) {
                if !accesses_ok(a) {
                    dangling("instance", i, "resource or allocation", a.alloc.0.min(a.resource.0));
                }
            }
        }
        for (c, copy) in self.copies.iter().enumerate() {
            for id in [copy.src_alloc, copy.dst_alloc] {
                if id.index() >= self.allocations.len() {
                    dangling("copy", c, "allocation", id.0);
                }
            }
            if copy.resource.index() >= self.resources.len() {
                dangling("copy", c, "resource", copy.resource.0);
            }
        }
        for (a, alloc) in self.allocations.iter().enumerate() {
            if alloc.resource.index() >= self.resources.len() {
                dangling("allocation", a, "resource", alloc.resource.0);
            }
        }
        for (p, pair) in self.history.iter().enumerate() {
            for id in [pair.current, pair.previous] {
                if id.index() >= self.allocations.len() {
                    dangling("history pair", p, "allocation", id.0);
                }
            }
        }
        errors
    }

    pub(crate) fn check_storage(&self, errors: &mut Vec<ScheduleError>) {
        let holds = |alloc: AllocId, a: &Access, device| {
            let info = self.allocation(alloc);
            info.resource == a.resource && info.device == device && info.versions.contains(&a.version)
        };
        for (i, inst) in self.instances.iter().enumerate() {
            let instance = InstanceId(i as u32);
            for a in inst.reads.iter().chain(&inst.writes) {
                if !holds(a.alloc, a, inst.device) {
                    let (resource, version, alloc) = (a.resource, a.version, a.alloc);
                    errors.push(ScheduleError::AllocationMismatch { instance, resource, version, alloc });
                }
            }
            for w in inst.writes.iter().filter(|w| !w.in_place) {
                if inst.reads.iter().any(|r| r.alloc == w.alloc) {
                    errors.push(ScheduleError::UndeclaredInPlace { instance, alloc: w.alloc });
                }
            }
            for w in inst.writes.iter().filter(|w| w.in_place) {
                let replaced = inst.reads.iter().find(|r| r.resource == w.resource && r.version + 1 == w.version);
                if let Some(r) = replaced.filter(|r| r.alloc != w.alloc) {
                    errors.push(ScheduleError::InPlaceElsewhere {
                        instance,
                        resource: w.resource,
                        version: w.version,
                        read: r.alloc,
                        written: w.alloc,
                    });
                }
            }
        }
        for (c, copy) in self.copies.iter().enumerate() {
            let (src, dst) = (self.allocation(copy.src_alloc), self.allocation(copy.dst_alloc));
            let fits = |info: &crate::schedule::Allocation, device| {
                info.resource == copy.resource && info.device == device && info.versions.contains(&copy.version)
            };
            if !fits(src, copy.from) || !fits(dst, copy.to) {
                errors.push(ScheduleError::CopyAllocationMismatch { copy: CopyId(c as u32) });
            }
        }
        self.check_hazards(errors);
    }

    /// Per device, in op order: no rows of an allocation are touched at an older version after
    /// a newer one was written over them (bands of one pass touch disjoint rows of one
    /// allocation at their own pace).
    fn check_hazards(&self, errors: &mut Vec<ScheduleError>) {
        for program in &self.devices {
            let mut written: HashMap<AllocId, Vec<(u32, Region, Op)>> = HashMap::new();
            for &op in &program.ops {
                let (reads, writes): (Touches, Touches) = match op {
                    Op::Pass(i) => {
                        let inst = self.instance(i);
                        (
                            inst.reads.iter().map(|a| (a.alloc, a.version, a.region)).collect(),
                            inst.writes.iter().map(|a| (a.alloc, a.version, a.region)).collect(),
                        )
                    }
                    Op::CopyOut(c) => {
                        let copy = self.copy(c);
                        (vec![(copy.src_alloc, copy.version, copy.region)], vec![])
                    }
                    Op::CopyIn(c) => {
                        let copy = self.copy(c);
                        (vec![], vec![(copy.dst_alloc, copy.version, copy.region)])
                    }
                    Op::Signal(_) | Op::Wait(_) => continue,
                };
                for &(alloc, version, region) in reads.iter().chain(&writes) {
                    let newer = written
                        .get(&alloc)
                        .into_iter()
                        .flatten()
                        .find(|(v, r, _)| *v > version && r.intersect(region).is_some());
                    if let Some(&(newer_version, _, earlier)) = newer {
                        errors.push(ScheduleError::AllocationHazard {
                            alloc,
                            device: program.device,
                            earlier,
                            earlier_version: newer_version,
                            later: op,
                            later_version: version,
                        });
                    }
                }
                for (alloc, version, region) in writes {
                    written.entry(alloc).or_default().push((version, region, op));
                }
            }
        }
    }

    /// The instances of each (pass, view) cover rows `0..height` exactly once.
    pub(crate) fn check_bands(&self, errors: &mut Vec<ScheduleError>) {
        let mut bands: HashMap<(PassId, ViewId), Vec<Region>> = HashMap::new();
        for inst in &self.instances {
            bands.entry((inst.pass, inst.view)).or_default().push(inst.region);
        }
        let mut broken: Vec<(PassId, ViewId)> = bands
            .into_iter()
            .filter_map(|(key, mut regions)| {
                regions.sort();
                let mut end = 0;
                let tiles = regions.iter().all(|r| {
                    let next = r.y0 == end && r.y1 > r.y0;
                    end = r.y1;
                    next
                }) && end == self.height;
                (!tiles).then_some(key)
            })
            .collect();
        broken.sort();
        errors.extend(broken.into_iter().map(|(pass, view)| ScheduleError::BandsDoNotTile {
            pass,
            view,
            height: self.height,
        }));
    }

    /// Every resource has texels (or bytes), and every access and copy covers a non-empty band
    /// of its resource's rows: the executor records barriers and copies of exactly those rows.
    pub(crate) fn check_shapes(&self, errors: &mut Vec<ScheduleError>) {
        for (r, info) in self.resources.iter().enumerate() {
            let empty = match info.desc {
                ResourceDesc::Image { width, height, .. } => width == 0 || height == 0,
                ResourceDesc::Buffer { .. } => false,
                ResourceDesc::RowBuffer { rows, row_bytes } => rows == 0 || row_bytes == 0,
            };
            if empty {
                errors.push(ScheduleError::EmptyResource { resource: ResourceId(r as u32) });
            }
        }
        let mut outside = |what, index: usize, resource: ResourceId, rows: Region| {
            let height = self.resource(resource).desc.rows();
            if rows.y0 >= rows.y1 || rows.y1 > height {
                errors.push(ScheduleError::RowsOutsideResource { what, index: index as u32, resource, rows, height });
            }
        };
        for (i, inst) in self.instances.iter().enumerate() {
            for a in inst.reads.iter().chain(&inst.writes).chain(&inst.history_reads) {
                outside("instance", i, a.resource, a.region);
            }
        }
        for (c, copy) in self.copies.iter().enumerate() {
            outside("copy", c, copy.resource, copy.region);
        }
    }
}

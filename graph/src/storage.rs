//! Storage assignment: which allocation holds each version of each resource on each device.
//!
//! The rule is the simplest one that is always safe: every version a device holds gets an
//! allocation of its own, except a version written in place ([`crate::PassBuilder::modify`]),
//! which stays in the allocation of the version it replaces. So no pass ever writes storage that
//! a pass still to run reads as another version, and `Schedule::validate()` can check that
//! claim on the plain data. Reusing dead allocations for later versions (aliasing) would save
//! memory and needs a liveness proof per device; it is left for when a pipeline's footprint
//! asks for it.
//!
//! A resource read as history keeps its final version in a double-buffered allocation: frame
//! f writes one half, history reads see the other half (frame f − 1's), and the halves swap by
//! frame parity.

use std::collections::HashMap;

use crate::ids::{AllocId, DeviceId, InstanceId, ResourceId};
use crate::schedule::{Allocation, CrossCopy, PassInstance};

type Key = (ResourceId, DeviceId, u32);

#[derive(Default)]
struct Storage {
    allocations: Vec<Allocation>,
    by_version: HashMap<Key, AllocId>,
}

impl Storage {
    /// The allocation of `version` of `resource` on `device`, created if it has none.
    fn of(&mut self, resource: ResourceId, device: DeviceId, version: u32) -> AllocId {
        if let Some(&id) = self.by_version.get(&(resource, device, version)) {
            return id;
        }
        let id = AllocId(self.allocations.len() as u32);
        self.allocations.push(Allocation { resource, device, versions: vec![version], history: false });
        self.by_version.insert((resource, device, version), id);
        id
    }

    /// Puts `version` into the allocation that holds `replaced` (an in-place write).
    fn extend(&mut self, resource: ResourceId, device: DeviceId, replaced: u32, version: u32) -> AllocId {
        let id = self.of(resource, device, replaced);
        if let Some(&existing) = self.by_version.get(&(resource, device, version)) {
            return existing;
        }
        let versions = &mut self.allocations[id.index()].versions;
        versions.push(version);
        versions.sort_unstable();
        self.by_version.insert((resource, device, version), id);
        id
    }
}

/// Gives every access and copy of a compiled frame its allocation; returns the allocations.
/// `order` is the frame's topological order (in-place writes need the allocation of the version
/// they replace, which an earlier instance created).
pub(crate) fn assign_storage(
    instances: &mut [PassInstance],
    copies: &mut [CrossCopy],
    order: &[InstanceId],
) -> Vec<Allocation> {
    let mut storage = Storage::default();
    for &id in order {
        let inst = &mut instances[id.index()];
        let device = inst.device;
        for read in &mut inst.reads {
            read.alloc = storage.of(read.resource, device, read.version);
        }
        for write in &mut inst.writes {
            write.alloc = if write.in_place && write.version > 0 {
                storage.extend(write.resource, device, write.version - 1, write.version)
            } else {
                storage.of(write.resource, device, write.version)
            };
        }
    }
    // Copies after every instance: a copy into a device that also writes the version in place
    // (its own band of a `modify`) must land in that in-place allocation. Assigned at its
    // producer instead, a copy that came first in the order made the version a fresh allocation
    // there, and the in-place write then went into it rather than into the allocation that holds
    // the rows it did not touch.
    for copy in copies.iter_mut() {
        copy.src_alloc = storage.of(copy.resource, copy.from, copy.version);
        copy.dst_alloc = storage.of(copy.resource, copy.to, copy.version);
    }
    // History last: the version it reads is written later in the frame.
    for inst in instances.iter_mut() {
        let device = inst.device;
        for read in &mut inst.history_reads {
            read.alloc = storage.of(read.resource, device, read.version);
            storage.allocations[read.alloc.index()].history = true;
        }
    }
    storage.allocations
}

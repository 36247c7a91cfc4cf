//! Lowering an ordered set of placed instances to per-device programs.
//!
//! A cross-device copy is inserted exactly where an edge joins two devices: one copy per
//! (producer write, destination device), covering only the rows consumers there read. The
//! producer side (CopyOut, Signal) follows the producer at once so transfers overlap with later
//! work; the consumer side (Wait, CopyIn) sits just before the first consumer on its device.
//! Because every device's op order is a subsequence of one global topological order, a wait can
//! only name a signal that comes earlier in that order: the programs cannot deadlock.

use std::collections::{BTreeMap, HashMap};

use crate::ids::{AllocId, CopyId, DeviceId, InstanceId, Region, ResourceId};
use crate::schedule::{CopyKind, CrossCopy, DeviceProgram, Edge, Op, PassInstance, ResourceInfo};

/// Key of one copy: producer instance, resource, version, destination device.
type CopyKey = (InstanceId, ResourceId, u32, DeviceId);

pub(crate) fn lower(
    device_count: u32,
    instances: &[PassInstance],
    edges: &[Edge],
    resources: &[ResourceInfo],
    order: &[InstanceId],
) -> (Vec<DeviceProgram>, Vec<CrossCopy>) {
    let position: HashMap<InstanceId, usize> = order.iter().enumerate().map(|(i, &id)| (id, i)).collect();

    // Rows each destination needs from each producer write, and its earliest consumer there.
    let mut needs: BTreeMap<CopyKey, (Region, InstanceId)> = BTreeMap::new();
    for e in edges {
        let (p, c) = (&instances[e.producer.index()], &instances[e.consumer.index()]);
        if p.device == c.device {
            continue;
        }
        let key = (e.producer, e.access.resource, e.access.version, c.device);
        let entry = needs.entry(key).or_insert((e.access.region, e.consumer));
        entry.0 = hull(entry.0, e.access.region);
        if position[&e.consumer] < position[&entry.1] {
            entry.1 = e.consumer;
        }
    }

    // Finished outputs produced away from device 0 travel there at the end.
    let mut gathers: BTreeMap<CopyKey, Region> = BTreeMap::new();
    for (i, inst) in instances.iter().enumerate() {
        if inst.device == DeviceId(0) {
            continue;
        }
        for w in &inst.writes {
            let info = &resources[w.resource.index()];
            if info.exported == Some(w.version) {
                gathers.insert((InstanceId(i as u32), w.resource, w.version, DeviceId(0)), w.region);
            }
        }
    }

    // A finished output that a consumer on device 0 already receives travels once: its
    // dependency copy grows to the whole written band and doubles as the gather.
    gathers.retain(|key, region| match needs.get_mut(key) {
        Some(need) => {
            need.0 = hull(need.0, *region);
            false
        }
        None => true,
    });

    // Number copies in the order their producers run, so ids are stable and readable.
    let mut copies = Vec::new();
    let mut outgoing: HashMap<InstanceId, Vec<CopyId>> = HashMap::new();
    let mut incoming: HashMap<InstanceId, Vec<CopyId>> = HashMap::new();
    let mut gathered_last = Vec::new();
    for &producer in order {
        let from = instances[producer.index()].device;
        let range =
            (producer, ResourceId(0), 0, DeviceId(0))..=(producer, ResourceId(u32::MAX), u32::MAX, DeviceId(u32::MAX));
        // Allocations are assigned once every copy exists (storage.rs).
        let mut push = |resource: ResourceId, version, region, to, kind| {
            let id = CopyId(copies.len() as u32);
            let bytes = resources[resource.index()].desc.bytes(region);
            let (src_alloc, dst_alloc) = (AllocId::UNASSIGNED, AllocId::UNASSIGNED);
            copies.push(CrossCopy { resource, version, region, from, to, src_alloc, dst_alloc, bytes, kind });
            outgoing.entry(producer).or_default().push(id);
            id
        };
        for (&(_, resource, version, to), &(region, first)) in needs.range(range.clone()) {
            let id = push(resource, version, region, to, CopyKind::Dependency);
            incoming.entry(first).or_default().push(id);
        }
        for (&(_, resource, version, to), &region) in gathers.range(range) {
            gathered_last.push(push(resource, version, region, to, CopyKind::Gather));
        }
    }

    let mut devices: Vec<DeviceProgram> = (0..device_count)
        .map(|d| DeviceProgram { device: DeviceId(d), ops: Vec::new(), barriers: Vec::new() })
        .collect();
    for &id in order {
        let ops = &mut devices[instances[id.index()].device.index()].ops;
        for &c in incoming.get(&id).into_iter().flatten() {
            ops.extend([Op::Wait(c), Op::CopyIn(c)]);
        }
        ops.push(Op::Pass(id));
        for &c in outgoing.get(&id).into_iter().flatten() {
            ops.extend([Op::CopyOut(c), Op::Signal(c)]);
        }
    }
    if let Some(primary) = devices.first_mut() {
        for c in gathered_last {
            primary.ops.extend([Op::Wait(c), Op::CopyIn(c)]);
        }
    }
    (devices, copies)
}

fn hull(a: Region, b: Region) -> Region {
    Region { y0: a.y0.min(b.y0), y1: a.y1.max(b.y1) }
}

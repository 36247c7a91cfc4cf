//! `Schedule::validate()`: every invariant the executor relies on, checked on the plain data.
//! It recomputes what it needs from instances' reads and writes rather than trusting the
//! schedule's own edge list, so a corrupted schedule cannot vouch for itself.

use std::collections::{HashMap, VecDeque};

pub use crate::error::{ScheduleError, ValidationReport};
use crate::ids::{CopyId, DeviceId, InstanceId, Region, ResourceId};
use crate::schedule::{Op, Schedule};

/// Where each op sits: (device, index) for every occurrence.
type Positions = HashMap<Op, Vec<(DeviceId, usize)>>;

/// A copy's four ops by name, in the order they must run.
type CopyOpKinds = [(&'static str, fn(CopyId) -> Op); 4];

const COPY_OPS: CopyOpKinds =
    [("CopyOut", Op::CopyOut), ("Signal", Op::Signal), ("Wait", Op::Wait), ("CopyIn", Op::CopyIn)];

impl Schedule {
    pub fn validate(&self) -> ValidationReport {
        // Ids are checked first: every later check indexes by them.
        let mut errors = self.dangling_ids();
        if !errors.is_empty() {
            return ValidationReport { errors };
        }
        let mut positions: Positions = HashMap::new();
        for program in &self.devices {
            for (i, op) in program.ops.iter().enumerate() {
                positions.entry(*op).or_default().push((program.device, i));
            }
        }
        let at = |op: Op| positions.get(&op).and_then(|v| (v.len() == 1).then_some(v[0]));

        for (i, inst) in self.instances.iter().enumerate() {
            let instance = InstanceId(i as u32);
            match positions.get(&Op::Pass(instance)).map(Vec::as_slice) {
                None | Some([]) => errors.push(ScheduleError::InstanceNotScheduled { instance }),
                Some([(device, _)]) if *device != inst.device => {
                    errors.push(ScheduleError::InstanceOnWrongDevice { instance, placed: inst.device, listed: *device })
                }
                Some([_]) => {}
                Some(_) => errors.push(ScheduleError::InstanceScheduledTwice { instance }),
            }
        }

        let writers = self.writers();
        self.check_copies(&positions, &writers, &mut errors);
        self.check_reads(&at, &writers, &mut errors);
        self.check_gather(&at, &writers, &mut errors);
        if let Some((device, op)) = self.wait_cycle() {
            errors.push(ScheduleError::Deadlock { device, op });
        }
        self.check_storage(&mut errors);
        self.check_barriers(&mut errors);
        self.check_history(&mut errors);
        self.check_bands(&mut errors);
        self.check_shapes(&mut errors);
        self.check_globals(&mut errors);
        self.check_batches(&mut errors);
        ValidationReport { errors }
    }

    /// (resource, version) → (writer, rows written).
    fn writers(&self) -> HashMap<(ResourceId, u32), Vec<(InstanceId, Region)>> {
        let mut map: HashMap<_, Vec<_>> = HashMap::new();
        for (i, inst) in self.instances.iter().enumerate() {
            for w in &inst.writes {
                map.entry((w.resource, w.version)).or_default().push((InstanceId(i as u32), w.region));
            }
        }
        map
    }

    fn check_copies(
        &self,
        positions: &Positions,
        writers: &HashMap<(ResourceId, u32), Vec<(InstanceId, Region)>>,
        errors: &mut Vec<ScheduleError>,
    ) {
        for (c, copy) in self.copies.iter().enumerate() {
            let id = CopyId(c as u32);
            if copy.from == copy.to {
                errors.push(ScheduleError::CopyWithinDevice { copy: id });
            }
            let expected = self.resource(copy.resource).desc.bytes(copy.region);
            if expected != copy.bytes {
                errors.push(ScheduleError::CopyBytesMismatch { copy: id, expected, actual: copy.bytes });
            }
            let mut index = [None; 4];
            for (k, (name, make)) in COPY_OPS.iter().enumerate() {
                let device = if k < 2 { copy.from } else { copy.to };
                match positions.get(&make(id)).map(Vec::as_slice) {
                    Some([(d, i)]) if *d == device => index[k] = Some(*i),
                    Some([_, _, ..]) => errors.push(ScheduleError::CopyOpDuplicated { copy: id, op: name }),
                    _ => errors.push(ScheduleError::CopyOpMissing { copy: id, op: name }),
                }
            }
            if matches!(index, [Some(o), Some(s), _, _] if s < o) || matches!(index, [_, _, Some(w), Some(i)] if i < w)
            {
                errors.push(ScheduleError::CopyOpsOutOfOrder { copy: id });
            }
            let producers: Vec<(InstanceId, Region)> = writers
                .get(&(copy.resource, copy.version))
                .into_iter()
                .flatten()
                .filter(|(w, r)| self.instance(*w).device == copy.from && r.intersect(copy.region).is_some())
                .copied()
                .collect();
            if covered(copy.region, producers.iter().map(|p| p.1)) < copy.region.len() {
                errors.push(ScheduleError::CopyWithoutProducer { copy: id });
            }
            for (producer, _) in producers {
                let p = positions.get(&Op::Pass(producer)).and_then(|v| v.first()).map(|x| x.1);
                if let (Some(p), Some(out)) = (p, index[0])
                    && p > out
                {
                    errors.push(ScheduleError::CopyBeforeProducer { copy: id, producer });
                }
            }
        }
    }

    fn check_reads(
        &self,
        at: &dyn Fn(Op) -> Option<(DeviceId, usize)>,
        writers: &HashMap<(ResourceId, u32), Vec<(InstanceId, Region)>>,
        errors: &mut Vec<ScheduleError>,
    ) {
        // The copies of each (resource, version) from one device to another, built once: the
        // fine schemes have tens of thousands of copies and reads.
        let mut copies_between: HashMap<(ResourceId, u32, DeviceId, DeviceId), Vec<CopyId>> = HashMap::new();
        for (c, k) in self.copies.iter().enumerate() {
            copies_between.entry((k.resource, k.version, k.from, k.to)).or_default().push(CopyId(c as u32));
        }
        for (i, inst) in self.instances.iter().enumerate() {
            let consumer = InstanceId(i as u32);
            let Some((device, here)) = at(Op::Pass(consumer)) else {
                continue;
            };
            for read in &inst.reads {
                if read.version == 0 {
                    continue; // imported: present on every device before the frame
                }
                let mut satisfied = Vec::new();
                for &(producer, written) in writers.get(&(read.resource, read.version)).into_iter().flatten() {
                    let Some(overlap) = written.intersect(read.region) else {
                        continue;
                    };
                    let Some((pd, pi)) = at(Op::Pass(producer)) else {
                        continue;
                    };
                    if pd == device {
                        if pi > here {
                            errors.push(ScheduleError::OrderViolation { producer, consumer });
                        }
                        satisfied.push(overlap);
                        continue;
                    }
                    let copies: Vec<CopyId> = copies_between
                        .get(&(read.resource, read.version, pd, device))
                        .into_iter()
                        .flatten()
                        .copied()
                        .filter(|&c| self.copy(c).region.contains(overlap))
                        .collect();
                    match copies.as_slice() {
                        [] => {}
                        [c] => {
                            if at(Op::CopyIn(*c)).is_some_and(|(_, ci)| ci > here) {
                                errors.push(ScheduleError::CopyArrivesLate { copy: *c, consumer });
                            }
                            satisfied.push(overlap);
                        }
                        _ => errors.push(ScheduleError::AmbiguousRead {
                            instance: consumer,
                            resource: read.resource,
                            version: read.version,
                            copies,
                        }),
                    }
                }
                if covered(read.region, satisfied.into_iter()) < read.region.len() {
                    errors.push(ScheduleError::UnsatisfiedRead {
                        instance: consumer,
                        resource: read.resource,
                        version: read.version,
                        rows: read.region,
                    });
                }
            }
        }
    }

    fn check_gather(
        &self,
        at: &dyn Fn(Op) -> Option<(DeviceId, usize)>,
        writers: &HashMap<(ResourceId, u32), Vec<(InstanceId, Region)>>,
        errors: &mut Vec<ScheduleError>,
    ) {
        let primary = DeviceId(0);
        for (r, info) in self.resources.iter().enumerate() {
            let Some(version) = info.exported else {
                continue;
            };
            if version == 0 {
                continue;
            }
            let resource = ResourceId(r as u32);
            let local = writers
                .get(&(resource, version))
                .into_iter()
                .flatten()
                .filter(|(w, _)| at(Op::Pass(*w)).is_some_and(|(d, _)| d == primary))
                .map(|(_, region)| *region);
            let gathered = self
                .copies
                .iter()
                .enumerate()
                .filter(|(c, k)| {
                    k.resource == resource
                        && k.version == version
                        && k.to == primary
                        && at(Op::CopyIn(CopyId(*c as u32))).is_some_and(|(d, _)| d == primary)
                })
                .map(|(_, k)| k.region);
            let full = info.desc.full();
            if covered(full, local.chain(gathered)) < full.len() {
                errors.push(ScheduleError::ViewNotGathered { view: info.view, resource });
            }
        }
    }

    /// Program order plus signal → wait must be acyclic, or some device waits forever: then the
    /// first op of the lowest such device that can never run (a wait whose signal never comes).
    pub(crate) fn wait_cycle(&self) -> Option<(DeviceId, Op)> {
        let offsets: Vec<usize> = self
            .devices
            .iter()
            .scan(0, |acc, p| {
                let o = *acc;
                *acc += p.ops.len();
                Some(o)
            })
            .collect();
        let total: usize = self.devices.iter().map(|p| p.ops.len()).sum();
        let mut successors: Vec<Vec<usize>> = vec![Vec::new(); total];
        let mut signals: HashMap<CopyId, usize> = HashMap::new();
        let mut waits: Vec<(CopyId, usize)> = Vec::new();
        for (p, program) in self.devices.iter().enumerate() {
            for (i, op) in program.ops.iter().enumerate() {
                let node = offsets[p] + i;
                if i + 1 < program.ops.len() {
                    successors[node].push(node + 1);
                }
                match op {
                    Op::Signal(c) => {
                        signals.insert(*c, node);
                    }
                    Op::Wait(c) => waits.push((*c, node)),
                    _ => {}
                }
            }
        }
        for (c, w) in waits {
            if let Some(&s) = signals.get(&c) {
                successors[s].push(w);
            }
        }
        let mut indegree = vec![0usize; total];
        for s in successors.iter().flatten() {
            indegree[*s] += 1;
        }
        let mut ready: VecDeque<usize> = (0..total).filter(|&n| indegree[n] == 0).collect();
        let mut ran = vec![false; total];
        while let Some(n) = ready.pop_front() {
            ran[n] = true;
            for &s in &successors[n] {
                indegree[s] -= 1;
                if indegree[s] == 0 {
                    ready.push_back(s);
                }
            }
        }
        let (p, i) = self
            .devices
            .iter()
            .enumerate()
            .find_map(|(p, program)| (0..program.ops.len()).find(|&i| !ran[offsets[p] + i]).map(|i| (p, i)))?;
        Some((self.devices[p].device, self.devices[p].ops[i]))
    }
}

/// Rows of `target` covered by the union of `parts`.
fn covered(target: Region, parts: impl Iterator<Item = Region>) -> u32 {
    let mut pieces: Vec<Region> = parts.filter_map(|p| p.intersect(target)).collect();
    pieces.sort();
    let (mut total, mut end) = (0, target.y0);
    for p in pieces {
        let start = p.y0.max(end);
        if p.y1 > start {
            total += p.y1 - start;
            end = p.y1;
        }
    }
    total
}

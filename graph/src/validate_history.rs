//! The history rules of `Schedule::validate()`: the two halves of every [`HistoryPair`] are
//! distinct storage of one resource on one device, no allocation is a half of two pairs, the
//! previous half holds no version of the frame and nothing but history reads touches it, and
//! every history read sees the previous half of the pair whose current half holds the version
//! it names. Together these prove that swapping the halves by frame parity never lets a frame
//! overwrite what its own history reads see.

use std::collections::{HashMap, HashSet};

use crate::error::ScheduleError;
use crate::ids::{AllocId, InstanceId};
use crate::schedule::{HistoryPair, Op, Schedule};

impl Schedule {
    pub(crate) fn check_history(&self, errors: &mut Vec<ScheduleError>) {
        self.check_pairs(errors);
        let previous: HashSet<AllocId> = self.history.iter().map(|p| p.previous).collect();
        self.check_previous_untouched(&previous, errors);
        self.check_history_reads(errors);
    }

    fn check_pairs(&self, errors: &mut Vec<ScheduleError>) {
        let mut halves: HashMap<AllocId, u32> = HashMap::new();
        for (p, &HistoryPair { current, previous }) in self.history.iter().enumerate() {
            let pair = p as u32;
            if current == previous {
                errors.push(ScheduleError::HistoryHalvesAlias { pair, alloc: current });
                continue;
            }
            let (c, q) = (self.allocation(current), self.allocation(previous));
            if c.resource != q.resource || c.device != q.device {
                errors.push(ScheduleError::HistoryHalvesDiffer { pair, current, previous });
            }
            if !q.versions.is_empty() {
                errors.push(ScheduleError::PreviousHalfHoldsVersions { alloc: previous, versions: q.versions.clone() });
            }
            for alloc in [current, previous] {
                *halves.entry(alloc).or_default() += 1;
            }
        }
        let mut shared: Vec<AllocId> = halves.into_iter().filter(|&(_, n)| n > 1).map(|(a, _)| a).collect();
        shared.sort_unstable();
        errors.extend(shared.into_iter().map(|alloc| ScheduleError::HistoryHalfShared { alloc }));
    }

    /// No read, write or copy of the frame touches a previous half.
    fn check_previous_untouched(&self, previous: &HashSet<AllocId>, errors: &mut Vec<ScheduleError>) {
        let mut touched = |alloc: AllocId, op: Op| {
            if previous.contains(&alloc) {
                errors.push(ScheduleError::PreviousHalfTouched { alloc, op });
            }
        };
        for (i, inst) in self.instances.iter().enumerate() {
            for a in inst.reads.iter().chain(&inst.writes) {
                touched(a.alloc, Op::Pass(InstanceId(i as u32)));
            }
        }
        for (c, copy) in self.copies.iter().enumerate() {
            let id = crate::ids::CopyId(c as u32);
            touched(copy.src_alloc, Op::CopyOut(id));
            touched(copy.dst_alloc, Op::CopyIn(id));
        }
    }

    /// Each history read sees the previous half of a pair of its own device and resource,
    /// whose current half holds the version the read names.
    fn check_history_reads(&self, errors: &mut Vec<ScheduleError>) {
        for (i, inst) in self.instances.iter().enumerate() {
            let instance = InstanceId(i as u32);
            for h in &inst.history_reads {
                let (resource, alloc) = (h.resource, h.alloc);
                let info = self.allocation(alloc);
                if info.device != inst.device || info.resource != resource {
                    errors.push(ScheduleError::HistoryOnOtherDevice { instance, resource, alloc });
                }
                let Some(pair) = self.history_pair_of_previous(alloc) else {
                    errors.push(ScheduleError::HistoryReadOutsidePair { instance, resource, alloc });
                    continue;
                };
                if !self.allocation(pair.current).versions.contains(&h.version) {
                    let (version, current) = (h.version, pair.current);
                    errors.push(ScheduleError::HistoryVersionNotCurrent { instance, resource, version, current });
                }
            }
        }
    }
}

//! The rules of `Schedule::validate()` for global resources (`Graph::global_buffer`,
//! `global_image`): one resource for the whole light field, so one writer per version (the one
//! instance of a `Role::Global` pass), and every access covers all of it (a band of a global
//! resource would leave the rest of it stale on the devices it is copied to).

use std::collections::HashMap;

use crate::error::ScheduleError;
use crate::ids::{InstanceId, PassId};
use crate::schedule::{Access, Schedule};
use crate::scope::Role;

impl Schedule {
    pub(crate) fn check_globals(&self, errors: &mut Vec<ScheduleError>) {
        let mut instances_of: HashMap<PassId, u32> = HashMap::new();
        for (i, inst) in self.instances.iter().enumerate() {
            let instance = InstanceId(i as u32);
            let global_pass = self.passes[inst.pass.index()].role == Role::Global;
            if global_pass {
                *instances_of.entry(inst.pass).or_default() += 1;
            }
            for w in &inst.writes {
                if self.resource(w.resource).global && !global_pass {
                    errors.push(ScheduleError::GlobalWrittenPerView { instance, resource: w.resource });
                }
            }
            let partial = |a: &&Access| {
                let info = self.resource(a.resource);
                info.global && a.region != info.desc.full()
            };
            let accesses = inst.reads.iter().chain(&inst.writes).chain(&inst.history_reads);
            for a in accesses.filter(partial) {
                errors.push(ScheduleError::GlobalAccessedInPart { instance, resource: a.resource, rows: a.region });
            }
        }
        let mut split: Vec<(PassId, u32)> = instances_of.into_iter().filter(|&(_, n)| n > 1).collect();
        split.sort_unstable();
        for (pass, instances) in split {
            errors.push(ScheduleError::GlobalPassInstances { pass, instances });
        }
    }
}

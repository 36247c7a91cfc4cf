//! A schedule proven sound once. Compiling checks what it built (`Schedule::validate`) and
//! hands out a [`ProvenSchedule`]: the backend takes only that, so holding one is the proof and
//! nothing checks the schedule again on the way to the GPU. It reads as a `Schedule`; taking the
//! data back to change it (`into_schedule`) drops the proof, and `Schedule::proven` checks a
//! changed or hand-built schedule again.

use std::ops::Deref;

use serde::Serialize;

use crate::error::ValidationReport;
use crate::schedule::Schedule;

/// A schedule `validate()` found sound.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct ProvenSchedule(Schedule);

impl ProvenSchedule {
    /// The plain schedule, to change it: the result is no longer proven.
    pub fn into_schedule(self) -> Schedule {
        self.0
    }
}

impl Deref for ProvenSchedule {
    type Target = Schedule;

    fn deref(&self) -> &Schedule {
        &self.0
    }
}

impl Schedule {
    /// This schedule, proven: every invariant `validate()` checks holds. Otherwise every broken
    /// one.
    pub fn proven(self) -> Result<ProvenSchedule, ValidationReport> {
        let report = self.validate();
        if report.is_ok() { Ok(ProvenSchedule(self)) } else { Err(report) }
    }
}

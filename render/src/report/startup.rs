//! How long a render takes to reach its first frame: render.json's `startup`. Each step's end
//! is host CLOCK_MONOTONIC time (`parallax_backend::host_now_ns`, the clock of the executor's
//! reports), given in milliseconds since planning started, once the arguments were read.

use parallax_backend::host_now_ns;
use serde::Serialize;

/// The steps of a render's start, in the order they end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Step {
    /// The arguments checked and the schedule compiled and proven.
    Planned,
    /// The scene read and imported.
    SceneLoaded,
    /// The Vulkan devices created.
    Devices,
    /// The executor built: the plan's images and buffers, staging and links, the scene uploaded.
    Executor,
    /// The first frame (a warm-up frame unless `--warmup 0`) done, as the host saw it: the
    /// executor's `first_frame_done_ns`, which includes recording the command buffers.
    FirstFrame,
}

/// When each step of a render's start ended.
#[derive(Clone, Debug)]
pub struct Startup {
    started_ns: u64,
    ended_ns: Vec<(Step, u64)>,
}

impl Startup {
    /// Starts the clock: now.
    pub fn start() -> Self {
        Self { started_ns: host_now_ns(), ended_ns: Vec::new() }
    }

    /// `step` ended now.
    pub fn ended(&mut self, step: Step) {
        self.ended_at(step, host_now_ns());
    }

    /// `step` ended at `ns` (host CLOCK_MONOTONIC).
    pub fn ended_at(&mut self, step: Step, ns: u64) {
        self.ended_ns.push((step, ns));
    }

    /// `{step_ms: milliseconds since the start}` for each step that ended.
    pub fn to_json(&self) -> serde_json::Value {
        let since_start = |ns: u64| ns.saturating_sub(self.started_ns) as f64 / 1e6;
        let fields = self.ended_ns.iter().map(|&(step, ns)| {
            let name = serde_json::to_value(step).expect("a step serialises as its name");
            (format!("{}_ms", name.as_str().expect("a step's name is a string")), since_start(ns).into())
        });
        serde_json::Value::Object(fields.collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_named_in_snake_case_with_their_unit_and_measured_from_the_start() {
        let mut startup = Startup { started_ns: 1_000_000, ended_ns: Vec::new() };
        startup.ended_at(Step::Planned, 3_500_000);
        startup.ended_at(Step::SceneLoaded, 4_000_000);
        startup.ended_at(Step::FirstFrame, 21_000_000);
        assert_eq!(
            startup.to_json(),
            serde_json::json!({ "planned_ms": 2.5, "scene_loaded_ms": 3.0, "first_frame_ms": 20.0 })
        );
    }
}

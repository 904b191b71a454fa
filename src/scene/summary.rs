//! What a run reports about itself: wall time per named phase ([`PhaseTimer`]) and the
//! `summary.json` value ([`Summary`]); writing the file is `output`'s job.

use std::time::{Duration, Instant};

use serde_json::{Map, Value};

use super::run::RunContext;

/// Accumulated wall time per named phase, in the order phases first ran.
#[derive(Clone, Debug, Default)]
pub struct PhaseTimer {
    phases: Vec<(String, Duration)>,
}

impl PhaseTimer {
    /// A timer with no phases.
    pub fn new() -> Self {
        Self::default()
    }

    /// Runs `work`, adding its wall time to `phase`, and returns its result.
    pub fn time<R>(&mut self, phase: &str, work: impl FnOnce() -> R) -> R {
        let start = Instant::now();
        let result = work();
        self.add(phase, start.elapsed());
        result
    }

    /// Adds the time elapsed since `start` to `phase` (for code a closure cannot wrap).
    pub fn add_since(&mut self, phase: &str, start: Instant) {
        self.add(phase, start.elapsed());
    }

    /// Adds `elapsed` to `phase`.
    pub fn add(&mut self, phase: &str, elapsed: Duration) {
        match self.phases.iter_mut().find(|(name, _)| name == phase) {
            Some((_, total)) => *total += elapsed,
            None => self.phases.push((phase.to_string(), elapsed)),
        }
    }

    /// Total time of `phase` (zero if it never ran).
    pub fn get(&self, phase: &str) -> Duration {
        self.phases
            .iter()
            .find(|(name, _)| name == phase)
            .map_or(Duration::ZERO, |(_, total)| *total)
    }

    /// The sum over all phases.
    pub fn total(&self) -> Duration {
        self.phases.iter().map(|(_, total)| *total).sum()
    }

    /// Phases and their totals, in the order they first ran.
    pub fn phases(&self) -> impl Iterator<Item = (&str, Duration)> {
        self.phases
            .iter()
            .map(|(name, total)| (name.as_str(), *total))
    }

    /// `{ phase: seconds, … }`.
    pub fn to_json(&self) -> Value {
        Value::Object(
            self.phases()
                .map(|(name, total)| (name.to_string(), Value::from(total.as_secs_f64())))
                .collect(),
        )
    }
}

/// Builds the summary of a run:
/// `{ scene, preset, inputs, threads, figures, wall_time_s, version }`.
///
/// ```
/// use ballast::scene::{PhaseTimer, RunContext, Summary};
///
/// let ctx = RunContext {
///     scene_path: "scenes/cantilever.toml".into(),
///     scene_name: "cantilever".into(),
///     preset: Some("quick".into()),
///     out_dir: "results/cantilever-quick".into(),
///     threads: Some(2),
///     overrides: Vec::new(),
/// };
/// let inputs: toml::Table = "steps = 10".parse().unwrap();
/// let mut timer = PhaseTimer::new();
/// timer.time("solve", || ());
/// let json = Summary::new(&ctx, &inputs)
///     .figure("tip_deflection_m", 9.2e-5)
///     .wall_times(&timer)
///     .to_json();
/// assert_eq!(json["inputs"]["steps"], 10);
/// assert_eq!(json["figures"]["tip_deflection_m"], 9.2e-5);
/// ```
#[derive(Clone, Debug)]
pub struct Summary {
    scene: String,
    preset: Option<String>,
    inputs: Value,
    threads: usize,
    figures: Map<String, Value>,
    wall_time_s: Value,
}

impl Summary {
    /// A summary of the run `ctx` with its merged scene `inputs`; the thread count is
    /// the requested one, or rayon's current pool size.
    pub fn new(ctx: &RunContext, inputs: &toml::Table) -> Self {
        Summary {
            scene: ctx.scene_name.clone(),
            preset: ctx.preset.clone(),
            inputs: toml_table_to_json(inputs),
            threads: ctx.threads.unwrap_or_else(rayon::current_num_threads),
            figures: Map::new(),
            wall_time_s: Value::Object(Map::new()),
        }
    }

    /// Records a headline figure (name it with its unit: `tip_deflection_m`).
    /// Non-finite numbers become `null`.
    pub fn figure(mut self, name: &str, value: impl Into<Value>) -> Self {
        self.figures.insert(name.to_string(), value.into());
        self
    }

    /// Records the wall time per phase.
    pub fn wall_times(mut self, timer: &PhaseTimer) -> Self {
        self.wall_time_s = timer.to_json();
        self
    }

    /// The summary as JSON.
    pub fn to_json(&self) -> Value {
        serde_json::json!({
            "scene": self.scene,
            "preset": self.preset,
            "inputs": self.inputs,
            "threads": self.threads,
            "figures": self.figures,
            "wall_time_s": self.wall_time_s,
            "version": env!("CARGO_PKG_VERSION"),
        })
    }
}

/// Converts TOML to JSON: datetimes become strings, non-finite floats `null`.
pub fn toml_to_json(value: &toml::Value) -> Value {
    match value {
        toml::Value::String(s) => Value::from(s.as_str()),
        toml::Value::Integer(i) => Value::from(*i),
        toml::Value::Float(f) => Value::from(*f),
        toml::Value::Boolean(b) => Value::from(*b),
        toml::Value::Datetime(d) => Value::from(d.to_string()),
        toml::Value::Array(items) => Value::Array(items.iter().map(toml_to_json).collect()),
        toml::Value::Table(table) => toml_table_to_json(table),
    }
}

/// Converts a TOML table to a JSON object (see [`toml_to_json`]).
pub fn toml_table_to_json(table: &toml::Table) -> Value {
    Value::Object(
        table
            .iter()
            .map(|(key, value)| (key.clone(), toml_to_json(value)))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timer_accumulates_per_phase_in_order() {
        let mut timer = PhaseTimer::new();
        timer.add("detect", Duration::from_millis(2));
        timer.add("solve", Duration::from_millis(5));
        timer.add("detect", Duration::from_millis(3));
        assert_eq!(timer.time("update", || 7), 7);
        assert_eq!(timer.get("detect"), Duration::from_millis(5));
        assert_eq!(timer.get("absent"), Duration::ZERO);
        let names: Vec<&str> = timer.phases().map(|(name, _)| name).collect();
        assert_eq!(names, ["detect", "solve", "update"]);
        assert!(timer.total() >= Duration::from_millis(10));
        let json = timer.to_json();
        assert_eq!(json["solve"], 0.005);
    }

    #[test]
    fn summary_has_every_field() {
        let ctx = RunContext {
            scene_path: "scenes/impact.toml".into(),
            scene_name: "impact".into(),
            preset: None,
            out_dir: "results/impact".into(),
            threads: Some(3),
            overrides: Vec::new(),
        };
        let inputs: toml::Table =
            "a = 1\nb = \"x\"\nc = [1.5, nan]\nd = 1979-05-27\n[t]\ne = true\n"
                .parse()
                .unwrap();
        let json = Summary::new(&ctx, &inputs)
            .figure("peak_force_N", 12.5)
            .figure("bad", f64::NAN)
            .to_json();
        assert_eq!(json["scene"], "impact");
        assert_eq!(json["preset"], Value::Null);
        assert_eq!(json["threads"], 3);
        assert_eq!(json["version"], env!("CARGO_PKG_VERSION"));
        assert_eq!(
            json["inputs"],
            serde_json::json!({"a": 1, "b": "x", "c": [1.5, null], "d": "1979-05-27", "t": {"e": true}})
        );
        assert_eq!(
            json["figures"],
            serde_json::json!({"peak_force_N": 12.5, "bad": null})
        );
        assert_eq!(json["wall_time_s"], serde_json::json!({}));
    }
}

//! Checkpoint files shared by the solvers that resume a killed run (`ballast-nscd`,
//! `ballast-qdem` track scenes).
//!
//! A checkpoint is one bincode record (f64 kept bit for bit) whose first two fields are
//! a format tag and the merged scene text (after preset and `--set`), followed by
//! whatever the solver needs to continue. It is written whole to a temporary file and
//! renamed over the previous one, so a run killed at any moment leaves the previous
//! checkpoint or the new one, never half of one. Reading checks the tag and the scene
//! before decoding the rest, so a damaged file, another tool's file and a checkpoint
//! of another scene each give one line naming the file.
//!
//! When a checkpoint is written is a [`Cadence`]: every so many steps, and after so much
//! wall time since the last one.
//!
//! The wall time a run spent up to a checkpoint is kept beside it, in
//! [`CLOCKS_FILE`] ([`RunClocks`]), not in it: a resumed run's checkpoint stays
//! byte-identical to an uninterrupted run's, and the summary of a run done in pieces
//! still reports the time of all of them.

use std::path::Path;
use std::time::{Duration, Instant};

use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::scene::{PhaseTimer, Time};
use crate::{Error, Result};

/// The file name in a run's output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";

/// The file beside the checkpoint with the wall time spent up to it.
pub const CLOCKS_FILE: &str = "checkpoint-clocks.json";

/// When a run writes its checkpoint: after every `every`-th step (0: never, whatever
/// the wall time), and also after a step that ends `wall` or more of wall time after
/// the last checkpoint (or the run's start; zero: no such trigger).
///
/// Why both: a step's cost varies a hundredfold within one run (a `table3` packing
/// rains at a fraction of a second a step and finishes at a minute a step, 120 000
/// contacts solved to the tolerance), so a step count alone either writes needlessly
/// often or leaves hours to lose when a run is killed. The wall-time trigger bounds
/// the loss, as GROMACS's `-cpt` (15 min) does. Where a checkpoint lands does not
/// change the run: a resumed run continues bit for bit from any step.
#[derive(Debug, Clone)]
pub struct Cadence {
    every: u64,
    wall: Duration,
    last: Instant,
}

impl Cadence {
    /// Every `every` steps and every `wall` of wall time, counted from now.
    pub fn new(every: u64, wall: Time) -> Self {
        Cadence {
            every,
            wall: Duration::from_secs_f64(wall.si().max(0.0)),
            last: Instant::now(),
        }
    }

    /// Whether a checkpoint is due after step `step` (counted from the run's start).
    pub fn due(&self, step: u64) -> bool {
        self.due_at(step, Instant::now())
    }

    /// [`Self::due`] at the instant `now`.
    pub fn due_at(&self, step: u64, now: Instant) -> bool {
        self.every > 0
            && (step % self.every == 0
                || (!self.wall.is_zero() && now.saturating_duration_since(self.last) >= self.wall))
    }

    /// Notes that a checkpoint was written now: the wall time counts from here.
    pub fn written(&mut self) {
        self.last = Instant::now();
    }
}

/// The scenes' default wall time between checkpoints (`checkpoint_wall_every`): at
/// most half an hour of a killed run is lost.
pub fn default_checkpoint_wall_every() -> Time {
    Time::from_si(1800.0)
}

/// Wall time a run spent up to a checkpoint, over all the pieces it was run in.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RunClocks {
    /// The checkpoint's step.
    pub step: u64,
    /// How many runs (the first and each resume) the time was spent in.
    pub pieces: u32,
    /// Time stepping, output excluded (s).
    pub stepping_s: f64,
    /// Time writing frames (s).
    pub frames_s: f64,
    /// Wall time per named phase (s), in the order they first ran.
    pub phases: Vec<(String, f64)>,
}

impl RunClocks {
    /// The clocks at checkpoint `step` of a run in its `pieces`-th piece.
    pub fn at(step: u64, pieces: u32, stepping_s: f64, frames_s: f64, timer: &PhaseTimer) -> Self {
        RunClocks {
            step,
            pieces,
            stepping_s,
            frames_s,
            phases: timer
                .phases()
                .map(|(name, total)| (name.to_string(), total.as_secs_f64()))
                .collect(),
        }
    }

    /// The clocks at checkpoint `step` of the piece that follows these (the first
    /// piece follows the default clocks): this piece's stepping and frame times added.
    pub fn then(&self, step: u64, stepping_s: f64, frames_s: f64, timer: &PhaseTimer) -> Self {
        let (stepping, frames) = (self.stepping_s + stepping_s, self.frames_s + frames_s);
        RunClocks::at(step, self.pieces + 1, stepping, frames, timer)
    }

    /// For a run resumed at checkpoint `step` in `dir`: the clocks of the pieces
    /// before it, merged into its `timer`; when they are not known, the note the tool
    /// prints (its summary's times then cover this piece only).
    pub fn resume(
        dir: &Path,
        step: u64,
        timer: &mut PhaseTimer,
    ) -> std::result::Result<Self, String> {
        match Self::read(dir, step) {
            Some(clocks) => {
                for (name, seconds) in &clocks.phases {
                    timer.add(name, Duration::from_secs_f64(*seconds));
                }
                Ok(clocks)
            }
            None => Err(format!(
                "note: {} has no wall times for step {step}; the summary's times cover this \
                 run only",
                dir.join(CLOCKS_FILE).display()
            )),
        }
    }

    /// Writes the clocks atomically into `dir` (after its checkpoint).
    pub fn write(&self, dir: &Path) -> Result<()> {
        crate::output::write_json(dir.join(CLOCKS_FILE), self)
    }

    /// The clocks saved in `dir` for checkpoint `step`; `None` when there are none or
    /// they belong to another checkpoint (the run was killed between writing the two).
    pub fn read(dir: &Path, step: u64) -> Option<Self> {
        let text = std::fs::read_to_string(dir.join(CLOCKS_FILE)).ok()?;
        serde_json::from_str::<RunClocks>(&text)
            .ok()
            .filter(|c| c.step == step)
    }
}

/// The leading fields every checkpoint record starts with.
#[derive(Deserialize)]
struct Header {
    format: String,
    scene: String,
}

/// Writes `record` (a struct whose first fields are `format: String, scene: String`)
/// atomically to `path`.
pub fn write_checkpoint<T: Serialize>(path: &Path, record: &T) -> Result<()> {
    let bytes = bincode::serialize(record)
        .map_err(|e| Error::invalid(path, format!("cannot encode the checkpoint: {e}")))?;
    crate::output::write_atomic(path, &bytes)
}

/// Reads a checkpoint written by [`write_checkpoint`], checking that its tag is
/// `format` and that it was written for `scene` (the merged scene text).
pub fn read_checkpoint<T: DeserializeOwned>(path: &Path, format: &str, scene: &str) -> Result<T> {
    read_checkpoint_matching(path, format, |saved| saved == scene)
}

/// Reads a checkpoint as [`read_checkpoint`] does, but lets the current scene differ
/// from the saved one in the `run_control` keys ((table, key) of the merged scene):
/// keys that say how a run is driven (how often it checkpoints, how long a phase may
/// run), not what it computes.
pub fn read_checkpoint_allowing<T: DeserializeOwned>(
    path: &Path,
    format: &str,
    scene: &str,
    run_control: &[(&str, &str)],
) -> Result<T> {
    let current = scene_without(scene, run_control);
    read_checkpoint_matching(path, format, |saved| {
        current.is_some() && scene_without(saved, run_control) == current
    })
}

/// The merged scene text parsed, without the `keys` ((table, key)); `None` when it is
/// not TOML.
fn scene_without(scene: &str, keys: &[(&str, &str)]) -> Option<toml::Table> {
    let mut table: toml::Table = scene.parse().ok()?;
    for (section, key) in keys {
        if let Some(toml::Value::Table(t)) = table.get_mut(*section) {
            t.remove(*key);
        }
    }
    Some(table)
}

/// [`read_checkpoint`] with the scene test given: `matches(saved)` says whether the
/// saved merged scene text is one the current run may continue (a tool that lets a
/// resumed run change a run-control key compares the scenes without it).
pub fn read_checkpoint_matching<T: DeserializeOwned>(
    path: &Path,
    format: &str,
    matches: impl Fn(&str) -> bool,
) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let not_ours = |e: &dyn std::fmt::Display| {
        Error::invalid(path, format!("not a {format} file of this version ({e})"))
    };
    // bincode's default decoding stops after the header and ignores the rest.
    let header: Header = bincode::deserialize(&bytes).map_err(|e| not_ours(&e))?;
    if header.format != format {
        return Err(Error::invalid(
            path,
            format!("format \"{}\", expected \"{format}\"", header.format),
        ));
    }
    if !matches(&header.scene) {
        return Err(Error::invalid(
            path,
            "was written for another scene, preset or --set (resume with the same \
             arguments as the killed run)",
        ));
    }
    bincode::deserialize(&bytes).map_err(|e| not_ours(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Record {
        format: String,
        scene: String,
        x: Vec<f64>,
    }

    #[test]
    fn a_checkpoint_is_due_on_its_steps_or_after_its_wall_time() {
        let cadence = Cadence::new(100, Time::from_si(60.0));
        let start = cadence.last;
        let later = |s: u64| start + Duration::from_secs(s);
        assert!(!cadence.due_at(99, later(59)));
        assert!(cadence.due_at(100, later(0)));
        assert!(cadence.due_at(101, later(60)));
        let mut written = cadence.clone();
        written.written();
        assert!(!written.due_at(101, written.last + Duration::from_secs(59)));
        // No wall trigger: only the steps.
        let steps_only = Cadence::new(100, Time::from_si(0.0));
        assert!(!steps_only.due_at(101, later(86_400)));
        // No checkpoints at all: never, whatever the wall time.
        let never = Cadence::new(0, Time::from_si(60.0));
        assert!(!never.due_at(100, later(86_400)));
    }

    #[test]
    fn clocks_read_back_for_their_step_only() {
        let dir = tempfile::tempdir().unwrap();
        let mut timer = PhaseTimer::new();
        timer.add("solve", Duration::from_millis(1500));
        let clocks = RunClocks::default().then(200, 2.0, 0.25, &timer);
        assert_eq!(clocks, RunClocks::at(200, 1, 2.0, 0.25, &timer));
        clocks.write(dir.path()).unwrap();
        assert_eq!(RunClocks::read(dir.path(), 200), Some(clocks.clone()));
        assert_eq!(RunClocks::read(dir.path(), 300), None);
        let mut resumed = PhaseTimer::new();
        resumed.add("solve", Duration::from_millis(500));
        assert_eq!(
            RunClocks::resume(dir.path(), 200, &mut resumed),
            Ok(clocks.clone())
        );
        assert_eq!(resumed.get("solve"), Duration::from_secs(2));
        let next = clocks.then(300, 1.0, 0.5, &resumed);
        assert_eq!(
            (next.pieces, next.stepping_s, next.frames_s),
            (2, 3.0, 0.75)
        );
        let note = RunClocks::resume(dir.path(), 300, &mut resumed).unwrap_err();
        assert!(
            note.contains(CLOCKS_FILE) && note.contains("step 300"),
            "{note}"
        );
        assert_eq!(resumed.get("solve"), Duration::from_secs(2));
    }

    #[test]
    fn a_checkpoint_reads_back_and_refuses_other_tags_scenes_and_junk() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(CHECKPOINT_FILE);
        let record = Record {
            format: "tool checkpoint 1".into(),
            scene: "a = 1\n".into(),
            x: vec![0.1, f64::MIN_POSITIVE, -3.0e300],
        };
        write_checkpoint(&path, &record).unwrap();
        let back: Record = read_checkpoint(&path, "tool checkpoint 1", "a = 1\n").unwrap();
        assert_eq!(back, record);
        let err = |format: &str, scene: &str| {
            read_checkpoint::<Record>(&path, format, scene)
                .unwrap_err()
                .to_string()
        };
        assert!(err("other checkpoint 1", "a = 1\n").contains("expected \"other"));
        assert!(err("tool checkpoint 1", "a = 2\n").contains("another scene"));
        std::fs::write(&path, b"junk").unwrap();
        let junk = err("tool checkpoint 1", "a = 1\n");
        assert!(junk.contains("not a tool checkpoint 1 file"), "{junk}");
        assert!(
            junk.contains(CHECKPOINT_FILE) && !junk.contains('\n'),
            "{junk}"
        );
    }

    #[test]
    fn a_resumed_run_may_change_its_run_control_keys_only() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(CHECKPOINT_FILE);
        let scene = "[output]\ncheckpoint_every = 5\nframes = 2\n";
        let record = Record {
            format: "tool checkpoint 1".into(),
            scene: scene.into(),
            x: vec![1.0],
        };
        write_checkpoint(&path, &record).unwrap();
        let keys = [
            ("output", "checkpoint_every"),
            ("output", "checkpoint_wall_every"),
        ];
        let read = |scene: &str| {
            read_checkpoint_allowing::<Record>(&path, "tool checkpoint 1", scene, &keys)
        };
        assert_eq!(read(scene).unwrap(), record);
        let other_cadence =
            "[output]\ncheckpoint_every = 7\ncheckpoint_wall_every = \"1 h\"\nframes = 2\n";
        assert_eq!(read(other_cadence).unwrap(), record);
        let other_frames = "[output]\ncheckpoint_every = 5\nframes = 3\n";
        assert!(read(other_frames)
            .unwrap_err()
            .to_string()
            .contains("another scene"));
        assert!(read("not toml [")
            .unwrap_err()
            .to_string()
            .contains("another scene"));
    }
}

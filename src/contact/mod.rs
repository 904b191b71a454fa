//! Contact detection for NSCD bodies (seed 000 §2.1): broad phase, narrow phase with
//! parry3d, gap prediction with an alert distance, local frames and persistent contact
//! identities.
//!
//! - [`broad`]: sort-and-sweep on AABBs inflated by the alert distance; half-spaces are
//!   paired with every bounded body near their plane;
//! - [`narrow`]: a full separating-axis test (face normals and Minkowski edge–edge
//!   axes); points of the clipped reference faces and of crossing edges, each with its
//!   own normal, kept when their gap is at most the alert distance, so a contact about
//!   to close within the step is in the problem before it closes (LMGC90's gap
//!   prediction);
//! - [`frame`]: the local frame (normal, two tangents) of a contact, a function of the
//!   normal alone so a persistent contact keeps its tangents;
//! - [`ImpulseMemory`]: the previous step's impulses by [`ContactKey`] (body pair and
//!   parry feature ids), to warm-start the next step.
//!
//! Like the NSCD numerics, this module knows nothing of scenes or files: it takes
//! colliders and poses.

pub mod broad;
pub mod frame;
pub mod narrow;
pub mod shape;

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

pub use broad::{candidate_pairs, Candidate};
pub use frame::local_frame;
pub use narrow::{detect, Detector};
pub use shape::{Collider, ConvexShape, SphereCluster};

/// A contact's identity from step to step: the two bodies (in the order of the contact)
/// and the parry feature ids (vertex, edge or face codes) that touch.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub struct ContactKey {
    /// The first body (the normal points away from it).
    pub body_a: u32,
    /// The second body.
    pub body_b: u32,
    /// The feature of the first body.
    pub feature_a: u32,
    /// The feature of the second body.
    pub feature_b: u32,
}

/// A potential contact point found by the narrow phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint {
    /// Its identity.
    pub key: ContactKey,
    /// The contact point (world), midway between the two surfaces.
    pub point: Point3<f64>,
    /// Unit normal (world), from body a towards body b.
    pub normal: Vector3<f64>,
    /// The gap along the normal (m): negative when the bodies interpenetrate.
    pub gap: f64,
    /// The translation of body b's periodic image that this point touches (m; zero
    /// without periodicity or within the cell): body b's lever arm is taken from
    /// `position_b + shift_b`.
    pub shift_b: Vector3<f64>,
}

/// The impulses of the previous step, by contact identity, in each contact's local
/// frame (normal, tangent 1, tangent 2).
#[derive(Debug, Clone, Default)]
pub struct ImpulseMemory {
    impulses: HashMap<ContactKey, [f64; 3]>,
}

impl ImpulseMemory {
    /// An empty memory (cold start).
    pub fn new() -> Self {
        Self::default()
    }

    /// The stored impulse of `key`, or zero.
    pub fn get(&self, key: &ContactKey) -> [f64; 3] {
        self.impulses.get(key).copied().unwrap_or([0.0; 3])
    }

    /// Whether `key` had an impulse stored.
    pub fn contains(&self, key: &ContactKey) -> bool {
        self.impulses.contains_key(key)
    }

    /// Replaces the memory with this step's contacts and impulses.
    pub fn store<'a>(&mut self, entries: impl IntoIterator<Item = (ContactKey, &'a [f64; 3])>) {
        self.impulses.clear();
        for (key, r) in entries {
            self.impulses.insert(key, *r);
        }
    }

    /// Every stored key and impulse, sorted by key (for a checkpoint: the same memory
    /// gives the same list).
    pub fn entries(&self) -> Vec<(ContactKey, [f64; 3])> {
        let mut entries: Vec<_> = self.impulses.iter().map(|(k, r)| (*k, *r)).collect();
        entries.sort_unstable_by_key(|(k, _)| *k);
        entries
    }

    /// The memory holding `entries` (from [`Self::entries`]).
    pub fn from_entries(entries: &[(ContactKey, [f64; 3])]) -> Self {
        ImpulseMemory {
            impulses: entries.iter().copied().collect(),
        }
    }

    /// The number of stored contacts.
    pub fn len(&self) -> usize {
        self.impulses.len()
    }

    /// Whether nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.impulses.is_empty()
    }
}

//! The sphere buffers of a multi-body step, and which spheres a step must update.
//!
//! Each step gathers every sphere's position and velocity from its body, evaluates the
//! contacts and sums the sphere forces back onto the bodies. Between two rebuilds of
//! the Verlet list, [`Contacts::forces`] reads only the spheres that have a candidate
//! pair ([`Contacts::touched`]); on the paper bed of seed 004 §4 (1 999 rigid stones,
//! 118 089 vertex spheres) most spheres have none, and computing them was a fifth of
//! the step. So a step updates a rigid body's touched spheres only, as long as that
//! body cannot have moved any of its spheres by more than [`PARTIAL_SKIN_FRACTION`] of
//! the skin since the last rebuild. The bound is |Δc| + 2 sin(θ/2) r_max (Δc the move
//! of the mass centre, θ the turn since the rebuild, r_max the body's farthest sphere
//! centre). A body above it (on the move) has all its spheres updated, and only those
//! bodies' spheres and the node spheres are scanned for staleness: below the bound no
//! sphere left out can have moved the half skin that makes the list stale, so the
//! rebuild decisions, hence the step's bits, are those of a full update.
//!
//! A new list also copies its touched spheres' centres (in their bodies' frames) into
//! one table in the order of `active`, so a step reads them in a single sweep. Read
//! from each body's own table they missed the cache one by one: on the paper bed that
//! load was most of the gather's time, and the gather a quarter of the step
//! (measured 2026-12-07, `perf` on the five-car run).
//!
//! The touched spheres' positions and velocities also live in arrays of their own, in
//! the order of [`Contacts::touched`] ([`SphereBuffers::tx`], [`SphereBuffers::tv`]):
//! a partial step writes its rigid ones there directly, the force loop reads both
//! members of every pair from them, and the bodies sum their forces from them. Read
//! from the whole set's arrays (2.8 MB each on the paper bed) those loads missed the
//! cache: with the compact arrays the paper bed's step took 0.76 of its time on 1
//! thread (2026-12-07, 10 ms of the paper preset, three rounds each, the same bits).

use std::ops::Range;

use super::contacts::{ContactState, Contacts};
use super::rigid::RigidState;
use super::system::{MultiBody, SphereAt, PARALLEL_MIN_BODIES};
use rayon::prelude::*;

/// A step updates only the touched spheres while every rigid body's bound stays below
/// this fraction of the skin. The list goes stale at half the skin; the margin keeps
/// the rounding of the bound (≈ 1e-8 × r_max) far from deciding.
pub const PARTIAL_SKIN_FRACTION: f64 = 0.45;

/// Sphere positions, velocities and forces, with what tells a step which to update.
#[derive(Debug)]
pub struct SphereBuffers {
    /// Positions (m): current for every sphere a step updated.
    pub x: Vec<[f64; 3]>,
    /// Velocities (m/s), likewise.
    pub v: Vec<[f64; 3]>,
    /// The touched spheres' positions (m), in the order of [`Contacts::touched`]: what
    /// the force loop and the sums onto the bodies read (module doc).
    pub tx: Vec<[f64; 3]>,
    /// Their velocities (m/s).
    pub tv: Vec<[f64; 3]>,
    /// How many of the touched spheres are node spheres (they come first; the
    /// touched rigid spheres, `active`, follow).
    touched_nodes: usize,
    /// Per rigid body: the largest distance of a sphere centre from its mass centre.
    reach: Vec<f64>,
    /// Per rigid body: centre and orientation at the last rebuild (none until a
    /// rebuild was seen: after a resume every sphere is updated until the next one).
    poses: Option<Vec<([f64; 3], [f64; 4])>>,
    /// The touched rigid spheres, ascending, so grouped by body: body b's are
    /// `active[ranges[b]]`.
    active: Vec<u32>,
    /// Their centres in their body's principal frame, in the same order: a step reads
    /// them in one sweep instead of one body's table after another (module doc).
    offsets: Vec<[f64; 3]>,
    ranges: Vec<Range<usize>>,
    /// The rebuild count of the list `active` was taken from.
    active_at: Option<u64>,
    /// Per rigid body, whether the current step updates all its spheres (see
    /// [`Self::plan`]).
    whole: Vec<bool>,
}

/// The rigid spheres a step updates: `active[ranges[b]]` for body b.
#[derive(Debug, Clone, Copy)]
pub struct ActiveSpheres<'a> {
    /// Sphere indices, ascending.
    pub active: &'a [u32],
    /// Their centres in their body's principal frame.
    pub offsets: &'a [[f64; 3]],
    /// Per rigid body, its run in `active`.
    pub ranges: &'a [Range<usize>],
}

impl<'a> ActiveSpheres<'a> {
    /// Body b's touched spheres.
    pub fn of(self, b: usize) -> &'a [u32] {
        &self.active[self.ranges[b].clone()]
    }

    /// Body b's touched spheres and their centres in its principal frame.
    pub fn with_offsets(self, b: usize) -> (&'a [u32], &'a [[f64; 3]]) {
        let range = self.ranges[b].clone();
        (&self.active[range.clone()], &self.offsets[range])
    }
}

/// What a partial step updates: every sphere of the bodies marked `whole`, the touched
/// ones (`active`) of the others.
#[derive(Debug, Clone, Copy)]
pub struct Placement<'a> {
    /// The touched rigid spheres by body.
    pub active: ActiveSpheres<'a>,
    /// Per rigid body, whether all its spheres are updated.
    pub whole: &'a [bool],
}

impl<'a> Placement<'a> {
    /// The spheres of body b the step updates, with their centres in its principal
    /// frame: `None` for all of them.
    pub fn of(self, b: usize) -> Option<(&'a [u32], &'a [[f64; 3]])> {
        (!self.whole[b]).then(|| self.active.with_offsets(b))
    }
}

/// Positions and velocities of some spheres, to fill.
pub type SphereSlices<'a> = (&'a mut [[f64; 3]], &'a mut [[f64; 3]]);

/// What one gather writes ([`SphereBuffers::targets`]).
#[derive(Debug)]
pub struct GatherTargets<'a> {
    /// A partial step's placement; `None`: every sphere.
    pub only: Option<Placement<'a>>,
    /// Positions of the whole set.
    pub x: &'a mut [[f64; 3]],
    /// Velocities of the whole set.
    pub v: &'a mut [[f64; 3]],
    /// A partial step's touched rigid spheres' positions and velocities, in the order
    /// of `only`'s active spheres.
    pub touched: Option<SphereSlices<'a>>,
}

impl SphereBuffers {
    /// Buffers for `system`'s spheres, nothing known yet.
    pub fn new(system: &MultiBody) -> Self {
        let n = system.spheres.len();
        let reach = system
            .rigid
            .iter()
            .map(|shape| {
                shape
                    .spheres
                    .iter()
                    .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
                    .fold(0.0, f64::max)
            })
            .collect();
        SphereBuffers {
            x: vec![[0.0; 3]; n],
            v: vec![[0.0; 3]; n],
            tx: Vec::new(),
            tv: Vec::new(),
            touched_nodes: 0,
            reach,
            poses: None,
            active: Vec::new(),
            offsets: Vec::new(),
            ranges: vec![0..0; system.rigid.len()],
            active_at: None,
            whole: vec![true; system.rigid.len()],
        }
    }

    /// Forgets the last rebuild (a resumed run): steps update every sphere until the
    /// next one.
    pub fn forget(&mut self) {
        self.poses = None;
        self.active_at = None;
    }

    /// Plans a step: whether it may update only some rigid spheres (the list they
    /// come from is the current one), and if so marks `whole` the bodies that have
    /// moved far enough since the rebuild to make a sphere left out count (module
    /// doc).
    pub fn plan(&mut self, cstate: &ContactState, rigid: &[RigidState], skin: f64) -> bool {
        let Some(poses) = self.poses.as_ref() else {
            return false;
        };
        if self.active_at != Some(cstate.rebuilds) {
            return false;
        }
        let limit = PARTIAL_SKIN_FRACTION * skin;
        type Item<'a> = (
            ((&'a mut bool, &'a RigidState), &'a ([f64; 3], [f64; 4])),
            &'a f64,
        );
        let mark = |(((whole, r), (c, q)), &reach): Item<'_>| {
            *whole = moved_bound(r, c, q, reach) > limit;
        };
        if rigid.len() >= PARALLEL_MIN_BODIES {
            self.whole
                .par_iter_mut()
                .zip(rigid)
                .zip(poses)
                .zip(&self.reach)
                .for_each(mark);
        } else {
            self.whole
                .iter_mut()
                .zip(rigid)
                .zip(poses)
                .zip(&self.reach)
                .for_each(mark);
        }
        true
    }

    /// What a gather fills: for a partial step (`partial`), its [`Placement`], and
    /// the touched rigid spheres' entries of [`Self::tx`] and [`Self::tv`] (those of
    /// the bodies not marked whole are written there only); the whole set's position
    /// and velocity buffers.
    pub fn targets(&mut self, partial: bool) -> GatherTargets<'_> {
        let n = self.touched_nodes;
        let (only, touched) = if partial {
            let only = Placement {
                active: ActiveSpheres {
                    active: &self.active,
                    offsets: &self.offsets,
                    ranges: &self.ranges,
                },
                whole: &self.whole,
            };
            (Some(only), Some((&mut self.tx[n..], &mut self.tv[n..])))
        } else {
            (None, None)
        };
        GatherTargets {
            only,
            x: &mut self.x,
            v: &mut self.v,
            touched,
        }
    }

    /// The touched spheres' entries of [`Self::tx`] and [`Self::tv`] copied from the
    /// whole set's buffers: all of them after a gather of every sphere, the node
    /// spheres' only after a partial step's (`rigid_written`: the gather wrote the
    /// rigid ones there itself).
    pub fn fill_touched(&mut self, touched: &[u32], rigid_written: bool) {
        let n = if rigid_written {
            self.touched_nodes
        } else {
            touched.len()
        };
        for ((t, u), &s) in self.tx[..n].iter_mut().zip(&mut self.tv[..n]).zip(touched) {
            *t = self.x[s as usize];
            *u = self.v[s as usize];
        }
    }

    /// How many of the touched spheres are node spheres (the first ones).
    pub fn touched_nodes(&self) -> usize {
        self.touched_nodes
    }

    /// The spheres a partial step must scan for staleness: the node spheres and every
    /// sphere of the bodies marked whole, as ranges.
    pub fn scanned<'s>(&'s self, system: &'s MultiBody) -> impl Iterator<Item = Range<usize>> + 's {
        std::iter::once(0..system.node_spheres()).chain(
            system
                .rigid_spheres
                .iter()
                .zip(&self.whole)
                .filter(|(_, &whole)| whole)
                .map(|(range, _)| range.clone()),
        )
    }

    /// The touched rigid spheres of the current list (after [`Self::sync`]).
    pub fn active(&self) -> ActiveSpheres<'_> {
        ActiveSpheres {
            active: &self.active,
            offsets: &self.offsets,
            ranges: &self.ranges,
        }
    }

    /// Takes note of the list after an evaluation or refresh: on a rebuild, the rigid
    /// poses it was built at; for a new list, its touched rigid spheres by body.
    pub fn sync(
        &mut self,
        system: &MultiBody,
        contacts: &Contacts,
        cstate: &ContactState,
        rebuilt: bool,
        rigid: &[RigidState],
    ) {
        if rebuilt {
            self.poses = Some(rigid.iter().map(|r| (r.position, r.orientation)).collect());
        }
        if self.active_at == Some(cstate.rebuilds) {
            return;
        }
        let first_rigid = system.node_spheres();
        self.active.clear();
        self.active.extend(
            contacts
                .touched()
                .iter()
                .copied()
                .filter(|&s| s as usize >= first_rigid),
        );
        let mut start = 0;
        for (b, range) in self.ranges.iter_mut().enumerate() {
            let end = start
                + self.active[start..]
                    .iter()
                    .take_while(|&&s| {
                        matches!(system.spheres[s as usize], SphereAt::Rigid { body, .. } if body as usize == b)
                    })
                    .count();
            *range = start..end;
            start = end;
        }
        debug_assert_eq!(start, self.active.len());
        self.touched_nodes = contacts.touched().len() - self.active.len();
        self.tx.resize(contacts.touched().len(), [0.0; 3]);
        self.tv.resize(contacts.touched().len(), [0.0; 3]);
        self.offsets.clear();
        self.offsets.extend(
            self.active
                .iter()
                .map(|&s| match system.spheres[s as usize] {
                    SphereAt::Rigid { body, k } => system.rigid[body as usize].spheres[k as usize],
                    SphereAt::Node { .. } => unreachable!("the touched rigid spheres hold no node"),
                }),
        );
        self.active_at = Some(cstate.rebuilds);
    }
}

/// An upper bound on how far any sphere of a rigid body (within `reach` of its centre)
/// has moved since the pose (`centre`, `orientation`): |Δc| + 2 sin(θ/2) reach, with
/// cos(θ/2) = |q · q₀| for the unit quaternions.
fn moved_bound(r: &RigidState, centre: &[f64; 3], orientation: &[f64; 4], reach: f64) -> f64 {
    let d = [
        r.position[0] - centre[0],
        r.position[1] - centre[1],
        r.position[2] - centre[2],
    ];
    let unit = |q: &[f64; 4]| {
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
    };
    let (a, b) = (unit(&r.orientation), unit(orientation));
    let c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]).abs();
    let half_sine = (1.0 - (c * c).min(1.0)).sqrt();
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() + 2.0 * half_sine * reach
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};

    /// The bound holds the true motion of a point at `reach` for a move and a turn.
    #[test]
    fn the_bound_covers_a_sphere_moved_and_turned() {
        let q0 = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1);
        let dq = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.02);
        let q1 = dq * q0;
        let p = Vector3::new(0.03, -0.01, 0.02);
        let (c0, c1) = (
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(1.0004, 2.0, 2.9997),
        );
        let before = c0 + q0 * p;
        let after = c1 + q1 * p;
        let r = RigidState {
            position: c1.into(),
            orientation: [q1.w, q1.i, q1.j, q1.k],
            velocity: [0.0; 3],
            angular_momentum: [0.0; 3],
            force: [0.0; 3],
            torque: [0.0; 3],
        };
        let bound = moved_bound(&r, &c0.into(), &[q0.w, q0.i, q0.j, q0.k], p.norm());
        let moved = (after - before).norm();
        assert!(moved <= bound, "moved {moved}, bound {bound}");
        // Not loose: the turn's chord 2 sin(θ/2) |p| ≤ θ |p| and |Δc| are its parts.
        assert!(
            bound <= (c1 - c0).norm() + 0.02 * p.norm() + 1e-12,
            "bound {bound}"
        );
    }
}

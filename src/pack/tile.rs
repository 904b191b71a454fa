//! A long bed laid from one periodic bay (`[tile] bay = ...` in the bed scene): the
//! stones and sleepers of a bay packed periodic along the track, repeated end to end.
//!
//! Raining seed 000's 3.6 m, 7-sleeper slice whole would take ≥ 13 h of stepping on
//! two cores (docs/pack.md, "A bed by tiling"); one 0.5 m bay packed periodic along x
//! holds the same ballast per bay, since a periodic cell has no end walls to loosen
//! it. Its copies are laid so that its sleepers fall on the scene's nominal sleeper
//! positions (`x_k = L/2 + (k − (n−1)/2) s`): copy j shifts the bay by
//! `offset + j·L_bay`, with `offset` the scene's first sleeper less the bay's.
//!
//! - Periodic bed (`L = n·L_bay`): n copies, every body's mass centre wrapped into
//!   [0, L): the bed *is* the bay, n times, contacts across the seams included.
//! - Walled bed: every copy whose contact shape lies whole between the end walls
//!   (x ∈ [0, L]); the copies that cross a wall are left out (reported as
//!   `dropped`), and the final settle lets the stones beside the gaps they leave
//!   come to rest.

use std::path::Path;

use nalgebra::{Isometry3, Translation3};

use super::deposit::{Role, SleeperModel};
use super::packing::Packing;
use crate::nscd::body::Body;
use crate::nscd::scene::StoneShape;
use crate::{Error, Result};

/// How the bay is laid along the bed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lay {
    /// The bay's length along x (its period, m).
    pub bay_length: f64,
    /// Shift of copy 0 (m).
    pub offset: f64,
    /// The bed's length (m).
    pub length: f64,
    /// Periodic bed (else end walls at x = 0 and x = length).
    pub periodic: bool,
}

/// The copies of one bay item.
#[derive(Debug, Clone, PartialEq)]
pub struct Copies {
    /// The shifts along x of the copies laid.
    pub shifts: Vec<f64>,
    /// Copies that would cross an end wall (left out).
    pub dropped: usize,
}

impl Laid {
    /// How many sleepers were laid.
    pub fn sleepers(&self) -> usize {
        self.bodies
            .iter()
            .filter(|(_, r)| matches!(r, Role::Sleeper(_)))
            .count()
    }
}

impl Lay {
    /// How many whole bays a periodic bed holds (`length / bay_length`, rounded).
    pub fn bays(&self) -> usize {
        (self.length / self.bay_length).round() as usize
    }

    /// The copies of an item whose mass centre is at x = `centre` and whose contact
    /// shape spans `extent` along x (both in the bay's frame; the centre in the bay's
    /// cell [0, bay_length)): in a periodic bed one per bay, its centre wrapped into
    /// [0, length) (the extent does not matter: the bed continues through its ends);
    /// between walls, every copy whole inside [0, length], those that cross a wall
    /// counted as dropped.
    pub fn copies(&self, centre: f64, extent: [f64; 2]) -> Copies {
        let (lb, l) = (self.bay_length, self.length);
        if self.periodic {
            let shifts = (0..self.bays())
                .map(|j| {
                    let at = centre + self.offset + j as f64 * lb;
                    at.rem_euclid(l) - centre
                })
                .collect();
            return Copies { shifts, dropped: 0 };
        }
        // Copies that reach into [0, L] at all, then those whole inside it.
        let first = ((-extent[1] - self.offset) / lb).floor() as i64;
        let last = ((l - extent[0] - self.offset) / lb).ceil() as i64;
        let mut copies = Copies {
            shifts: Vec::new(),
            dropped: 0,
        };
        for j in first..=last {
            let shift = self.offset + j as f64 * lb;
            let (lo, hi) = (extent[0] + shift, extent[1] + shift);
            if lo >= 0.0 && hi <= l {
                copies.shifts.push(shift);
            } else if hi > 0.0 && lo < l {
                copies.dropped += 1;
            }
        }
        copies
    }
}

/// The extent along x of a body's contact shape (its hull's vertices, or its spheres'
/// centres, widened by the rounding or sphere radius).
fn x_extent(body: &Body) -> [f64; 2] {
    let round = body.shape.collider.round();
    let xs = body.world_vertices().into_iter().map(|p| p.x);
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    [lo - round, hi + round]
}

/// `pose` moved by `shift` along x.
fn shifted(pose: &Isometry3<f64>, shift: f64) -> Isometry3<f64> {
    Translation3::new(shift, 0.0, 0.0) * pose
}

/// The scene's sleeper, as the bay's must be.
pub struct SceneSleeper<'a> {
    /// Its model (shape, density, material).
    pub model: &'a SleeperModel,
    /// Its own frame from the mesh (or cuboid) frame.
    pub own_from_mesh: Isometry3<f64>,
    /// Its inertia scale ([`super::deposit::DepositSetup::sleeper_inertia_scale`]).
    pub inertia_scale: f64,
    /// A cuboid's size, or
    pub size: Option<[f64; 3]>,
    /// the mesh file.
    pub mesh: Option<&'a Path>,
    /// Centre-to-centre spacing (m).
    pub spacing: f64,
    /// The first sleeper's nominal x (m).
    pub first: f64,
    /// How many the bed has (the lay must put as many whole in it).
    pub count: usize,
}

/// The bed the bay is laid into, as the scene gives it.
pub struct Target<'a> {
    /// The stone family (the bay's meshes must be these, in this order).
    pub family: &'a [StoneShape],
    /// Stone density (kg/m³) and material index.
    pub stone: (f64, u32),
    /// The sleepers, if any.
    pub sleeper: Option<SceneSleeper<'a>>,
    /// Length and width (m).
    pub size: [f64; 2],
    /// Periodic along x (else end walls).
    pub periodic: bool,
    /// The crib ballast's level (m).
    pub crib_top: f64,
}

/// The laid bed: its bodies in order (stones, then sleepers by x) and what was laid.
pub struct Laid {
    /// Stones and sleepers with their roles.
    pub bodies: Vec<(Body, Role)>,
    /// Stones in the bay.
    pub bay_stones: usize,
    /// Stone copies left out at the end walls.
    pub dropped: usize,
}

/// Checks that the bay at `path` fits the bed (periodic, the same width, crib level,
/// stone family and sleepers, a whole number of sleeper spacings long, the bed's
/// sleeper count laid whole) and lays it;
/// errors are one line naming `path` and what does not fit.
pub fn lay_bay(bay: &Packing, path: &Path, bed: &Target) -> Result<Laid> {
    let fail = |what: String| Error::invalid(path, format!("key tile.bay: {what}"));
    if bay.sides != "periodic" {
        return Err(fail(format!(
            "the bay must be packed periodic along x (bed.sides = \"periodic\"), not \"{}\"",
            bay.sides
        )));
    }
    let [length, width] = bed.size;
    let bay_length = bay.container_max[0] - bay.container_min[0];
    let bay_width = bay.container_max[1] - bay.container_min[1];
    if (bay_width - width).abs() > 1e-9 * width {
        return Err(fail(format!(
            "the bay is {bay_width} m wide, the bed {width} m (bed.width)"
        )));
    }
    if let Some(top) = bay.crib_top_m.filter(|t| (t - bed.crib_top).abs() > 1e-9) {
        return Err(fail(format!(
            "the bay's crib ballast is struck off at {top} m, the bed's at {} m \
             (bed.depth + sleepers.embed)",
            bed.crib_top
        )));
    }
    let same_file = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let family = bed.family;
    let stone_meshes = bay
        .stones
        .iter()
        .filter_map(|p| p.mesh)
        .max()
        .map_or(0, |m| m + 1);
    let mismatch = bay.meshes.iter().zip(family).position(|(m, s)| {
        !same_file(&m.file, &s.file)
            || m.scale != s.scale
            || m.round_m != s.round()
            || m.spheres_m != s.spheres()
    });
    if stone_meshes > family.len() || bay.meshes.len() < family.len() || mismatch.is_some() {
        return Err(fail(format!(
            "the bay's stones are not the scene's family of {} meshes{}",
            family.len(),
            mismatch.map_or(String::new(), |i| format!(
                " (its mesh[{i}] is {} × {})",
                bay.meshes[i].file.display(),
                bay.meshes[i].scale
            ))
        )));
    }
    let offset = match &bed.sleeper {
        Some(s) => {
            let n = bay.sleepers.len();
            if n == 0 || (n as f64 * s.spacing - bay_length).abs() > 1e-9 * bay_length {
                return Err(fail(format!(
                    "a bay of {n} sleepers {} m apart is {} m long, this one {bay_length} m",
                    s.spacing,
                    n as f64 * s.spacing
                )));
            }
            for (i, p) in bay.sleepers.iter().enumerate() {
                let same = match (p.size, p.mesh) {
                    (Some(size), None) => s.size == Some(size),
                    (None, Some(m)) => s.mesh.is_some_and(|f| same_file(&bay.meshes[m].file, f)),
                    _ => false,
                };
                if !same {
                    return Err(fail(format!(
                        "its sleeper[{i}] is not the scene's sleeper (sleepers.size or \
                         sleepers.mesh)"
                    )));
                }
            }
            // The bay's first sleeper sits at half a spacing (its nominal place).
            s.first - 0.5 * s.spacing
        }
        None if bay.sleepers.is_empty() => 0.0,
        None => {
            return Err(fail(format!(
                "the bay has {} sleepers and the scene none",
                bay.sleepers.len()
            )))
        }
    };
    let lay = Lay {
        bay_length,
        offset,
        length,
        periodic: bed.periodic,
    };
    if bed.periodic {
        let n = lay.bays() as f64;
        if n < 1.0 || (n * bay_length - length).abs() > 1e-9 * length || offset.abs() > 1e-12 {
            return Err(fail(format!(
                "a periodic bed must be a whole number of {bay_length} m bays long, not \
                 {length} m"
            )));
        }
    }
    let (density, material) = bed.stone;
    let mut bodies = Vec::new();
    let mut dropped = 0;
    for (i, placement) in bay.stones.iter().enumerate() {
        let Some(f) = placement.mesh else {
            return Err(fail(format!(
                "its stone[{i}] is a cuboid, not a stone mesh"
            )));
        };
        let pose = placement.pose() * family[f].mesh_pose;
        let body = family[f].body(0, density, material, pose);
        let copies = lay.copies(body.position.x, x_extent(&body));
        dropped += copies.dropped;
        for shift in copies.shifts {
            let k = bodies.len();
            let body = family[f].body(k, density, material, shifted(&pose, shift));
            bodies.push((body, Role::Stone(f)));
        }
    }
    if let Some(s) = &bed.sleeper {
        let (model, inertia_scale) = (s.model, s.inertia_scale);
        let mut laid: Vec<Isometry3<f64>> = Vec::new();
        for placement in &bay.sleepers {
            let own = placement.pose() * s.own_from_mesh.inverse();
            let body = model.body("bay", own, inertia_scale);
            let copies = lay.copies(body.position.x, x_extent(&body));
            laid.extend(copies.shifts.iter().map(|&s| shifted(&own, s)));
        }
        if laid.len() != s.count {
            return Err(fail(format!(
                "laid along bed.length ({length} m) the bay puts {} sleepers whole in the \
                 bed, the scene has {} (sleepers.count)",
                laid.len(),
                s.count
            )));
        }
        laid.sort_by(|a, b| a.translation.x.total_cmp(&b.translation.x));
        for (k, own) in laid.into_iter().enumerate() {
            let body = model.body(&format!("sleeper_{}", k + 1), own, inertia_scale);
            bodies.push((body, Role::Sleeper(k)));
        }
    }
    Ok(Laid {
        bodies,
        bay_stones: bay.stones.len(),
        dropped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walled(offset: f64) -> Lay {
        Lay {
            bay_length: 0.5,
            offset,
            length: 3.6,
            periodic: false,
        }
    }

    #[test]
    fn a_walled_bed_takes_the_copies_whole_between_its_walls() {
        // A stone 0.1 m across at the bay's start: its copies at 0.05 + 0.5 j span
        // [0.05, 0.15] + 0.5 j, j = 0..6 inside 3.6 m; j = 7 spans [3.55, 3.65]:
        // across the wall.
        let c = walled(0.05).copies(0.05, [0.0, 0.1]);
        assert_eq!(c.shifts.len(), 7);
        assert_eq!(c.dropped, 1);
        assert!((c.shifts[0] - 0.05).abs() < 1e-15);
        // One that hangs over the bay's start (its centre in the cell, its hull not),
        // laid from x = 0: copy 0 crosses the wall there, copies 1–7 fit.
        let c = walled(0.0).copies(0.01, [-0.04, 0.06]);
        assert_eq!((c.shifts.len(), c.dropped), (7, 1));
        assert!((c.shifts[0] - 0.5).abs() < 1e-15);
        // In the middle of the bay: copies 0–6 fit, copies −1 and 7 lie wholly
        // outside ([−0.25, −0.15], [3.75, 3.85]): none dropped.
        let c = walled(0.05).copies(0.25, [0.2, 0.3]);
        assert_eq!((c.shifts.len(), c.dropped), (7, 0));
    }

    #[test]
    fn a_periodic_bed_takes_one_copy_per_bay_wrapped_into_the_cell() {
        let lay = Lay {
            bay_length: 0.5,
            offset: 0.0,
            length: 1.5,
            periodic: true,
        };
        let c = lay.copies(0.49, [0.44, 0.54]);
        assert_eq!(c.dropped, 0);
        let centres: Vec<f64> = c.shifts.iter().map(|s| 0.49 + s).collect();
        for (got, want) in centres.iter().zip([0.49, 0.99, 1.49]) {
            assert!((got - want).abs() < 1e-12, "{centres:?}");
        }
    }
}

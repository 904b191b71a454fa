//! The contact impulses of a packing's last step, so that a solver restarting the bed
//! starts warm.
//!
//! A bed at rest is held by its contact impulses. Restarted cold, the NLGS of the first
//! steps does not converge on a heap of hundreds of stones (docs/nscd.md: stacks
//! converge slowly), and the bed moves by up to a millimetre in its first 10 steps
//! before the warm start of later steps catches up. `ballast-pack` therefore writes
//! the impulses of its final step beside the packing (`contacts.csv`, named by the
//! packing's `contacts` key) and `ballast-nscd` seeds its first step with them.
//!
//! The file is a CSV, one row per contact point:
//!
//! ```text
//! a,b,x_m,y_m,z_m,impulse_x_Ns,impulse_y_Ns,impulse_z_Ns
//! wall 0,stone 12,0.31,-0.02,0.0,0.0,0.0,0.0118
//! stone 12,sleeper 1,…
//! ```
//!
//! `a` and `b` name the bodies (`wall k`: the k-th of the container's planes in
//! [`crate::nscd::packed::container_planes`]' order; `sleeper k`, `stone k`: the
//! packing's k-th), the point is the contact point (world, m), the impulse the one the
//! contact gave body `b` over the step (world, N·s; body `a` got its opposite). World
//! vectors, not the engine's contact keys: a solver numbers its bodies its own way and
//! its narrow phase may see a pair the other way round, so a restart finds each point
//! again by its pair of bodies and its position ([`warm_memory`]).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Point3, Vector3};

use crate::contact::{local_frame, ContactKey, ContactPoint, ImpulseMemory};
use crate::nscd::packed::container_planes;
use crate::nscd::step::SolvedContact;
use crate::pack::Packing;
use crate::{Error, Result};

/// The file `ballast-pack` writes beside `packing.toml`.
pub const CONTACTS_FILE: &str = "contacts.csv";

/// The file's header line.
pub const CONTACTS_HEADER: &str = "a,b,x_m,y_m,z_m,impulse_x_Ns,impulse_y_Ns,impulse_z_Ns";

/// A restarted point takes a stored impulse only from a stored point this close (m):
/// the bed read back is the bed written up to composing placements (1e-12 m), and the
/// contact points of one pair lie millimetres apart.
pub const MATCH_DISTANCE: f64 = 1e-7;

/// A body of the packing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BodyRef {
    /// The k-th plane of the container (floor first).
    Wall(usize),
    /// The packing's k-th sleeper.
    Sleeper(usize),
    /// The packing's k-th stone.
    Stone(usize),
}

impl std::fmt::Display for BodyRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BodyRef::Wall(k) => write!(f, "wall {k}"),
            BodyRef::Sleeper(k) => write!(f, "sleeper {k}"),
            BodyRef::Stone(k) => write!(f, "stone {k}"),
        }
    }
}

impl std::str::FromStr for BodyRef {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || format!("\"{s}\" is not \"wall K\", \"sleeper K\" or \"stone K\"");
        let (kind, index) = s.trim().split_once(' ').ok_or_else(bad)?;
        let k: usize = index.parse().map_err(|_| bad())?;
        match kind {
            "wall" => Ok(BodyRef::Wall(k)),
            "sleeper" => Ok(BodyRef::Sleeper(k)),
            "stone" => Ok(BodyRef::Stone(k)),
            _ => Err(bad()),
        }
    }
}

/// One contact point of the packing's last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedContact {
    /// The first body (the impulse on it is `-impulse`).
    pub a: BodyRef,
    /// The second body.
    pub b: BodyRef,
    /// The contact point (world, m).
    pub point: [f64; 3],
    /// The impulse on `b` over the step (world, N·s).
    pub impulse: [f64; 3],
}

/// The contacts of a bed at its final configuration: each point of `points` (a
/// detection there) with the impulse that `solved` (the last step's contacts, detected
/// at its start) gave the same key, turned into world axes. `refs` names each body
/// index. Points of the detection that the last step had not solved are left out
/// (they carried nothing).
pub fn packed_contacts(
    points: &[ContactPoint],
    solved: &[SolvedContact],
    refs: &[BodyRef],
) -> Vec<PackedContact> {
    let impulses: HashMap<ContactKey, Vector3<f64>> = solved
        .iter()
        .map(|c| (c.contact.key, c.world_impulse()))
        .collect();
    points
        .iter()
        .filter_map(|p| {
            let j = impulses.get(&p.key)?;
            Some(PackedContact {
                a: refs[p.key.body_a as usize],
                b: refs[p.key.body_b as usize],
                point: p.point.coords.into(),
                impulse: (*j).into(),
            })
        })
        .collect()
}

/// The CSV text of `contacts` (numbers in shortest round-trip form).
pub fn contacts_csv(contacts: &[PackedContact]) -> String {
    let mut out = String::with_capacity(120 * (contacts.len() + 1));
    let _ = writeln!(out, "{CONTACTS_HEADER}");
    for c in contacts {
        let [x, y, z] = c.point;
        let [jx, jy, jz] = c.impulse;
        let _ = writeln!(
            out,
            "{},{},{x:?},{y:?},{z:?},{jx:?},{jy:?},{jz:?}",
            c.a, c.b
        );
    }
    out
}

/// Parses a contacts CSV (`path` names it in errors: one line with the line number).
pub fn parse_contacts(path: &Path, text: &str) -> Result<Vec<PackedContact>> {
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, header)) if header.trim() == CONTACTS_HEADER => {}
        _ => {
            return Err(Error::invalid(
                path,
                format!("line 1: the header must be \"{CONTACTS_HEADER}\""),
            ))
        }
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let at = |what: String| Error::invalid(path, format!("line {}: {what}", i + 1));
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != 8 {
            return Err(at(format!("{} fields, 8 expected", fields.len())));
        }
        let body = |k: usize| fields[k].parse::<BodyRef>().map_err(&at);
        let mut numbers = [0.0; 6];
        for (n, field) in numbers.iter_mut().zip(&fields[2..]) {
            *n = field
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| at(format!("\"{field}\" is not a finite number")))?;
        }
        out.push(PackedContact {
            a: body(0)?,
            b: body(1)?,
            point: [numbers[0], numbers[1], numbers[2]],
            impulse: [numbers[3], numbers[4], numbers[5]],
        });
    }
    Ok(out)
}

/// Checks that every body `contacts` names is in `packing` (the container's planes as
/// [`container_planes`] builds them, its sleepers, its stones): one line naming the
/// row.
pub fn check_contacts(path: &Path, contacts: &[PackedContact], packing: &Packing) -> Result<()> {
    let walls = container_planes(
        Vector3::zeros(),
        [0.0, 1.0],
        [0.0, 1.0],
        packing.period().is_some(),
        0,
    )
    .len();
    for (i, c) in contacts.iter().enumerate() {
        for body in [c.a, c.b] {
            let (count, what) = match body {
                BodyRef::Wall(_) => (walls, "walls"),
                BodyRef::Sleeper(_) => (packing.sleepers.len(), "sleepers"),
                BodyRef::Stone(_) => (packing.stones.len(), "stones"),
            };
            let (BodyRef::Wall(k) | BodyRef::Sleeper(k) | BodyRef::Stone(k)) = body;
            if k >= count {
                return Err(Error::invalid(
                    path,
                    format!("line {}: {body}, but the packing has {count} {what}", i + 2),
                ));
            }
        }
    }
    Ok(())
}

/// Reads a contacts CSV.
pub fn read_contacts(path: &Path) -> Result<Vec<PackedContact>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_contacts(path, &text)
}

/// A stored contact point and the impulse on its pair's higher-numbered body.
type StoredPoint = (Point3<f64>, Vector3<f64>);

/// The warm-start memory of a restarted bed: each of `points` (the restart's first
/// detection) takes the impulse of the stored contact of the same two bodies whose
/// point lies within [`MATCH_DISTANCE`] of it, turned into the point's own frame and
/// sign (its normal from its body a to its body b). `index` maps a packing body to the
/// restart's body index (`None`: not built there). Returns the memory and how many
/// points took an impulse.
pub fn warm_memory(
    points: &[ContactPoint],
    contacts: &[PackedContact],
    index: impl Fn(BodyRef) -> Option<usize>,
) -> (ImpulseMemory, usize) {
    // Stored points by the restart's (unordered) pair, each with its impulse on the
    // pair's higher-numbered body.
    let mut by_pair: HashMap<(usize, usize), Vec<StoredPoint>> = HashMap::new();
    for c in contacts {
        let (Some(a), Some(b)) = (index(c.a), index(c.b)) else {
            continue;
        };
        let on_b = Vector3::from(c.impulse);
        let (pair, on_high) = if a < b {
            ((a, b), on_b)
        } else {
            ((b, a), -on_b)
        };
        by_pair
            .entry(pair)
            .or_default()
            .push((Point3::from(c.point), on_high));
    }
    let mut entries: Vec<(ContactKey, [f64; 3])> = Vec::new();
    for p in points {
        let (a, b) = (p.key.body_a as usize, p.key.body_b as usize);
        let Some(stored) = by_pair.get(&(a.min(b), a.max(b))) else {
            continue;
        };
        let nearest = stored
            .iter()
            .map(|(q, j)| ((q - p.point).norm(), j))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((distance, on_high)) = nearest {
            if distance <= MATCH_DISTANCE {
                let on_b = if b > a { *on_high } else { -on_high };
                let [n, t, s] = local_frame(&p.normal);
                entries.push((p.key, [n.dot(&on_b), t.dot(&on_b), s.dot(&on_b)]));
            }
        }
    }
    let matched = entries.len();
    (ImpulseMemory::from_entries(&entries), matched)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contacts_read_back_bit_for_bit_and_bad_rows_name_the_line() {
        let contacts = vec![
            PackedContact {
                a: BodyRef::Wall(0),
                b: BodyRef::Stone(12),
                point: [0.1 + 0.2, -1.0 / 3.0, 0.0],
                impulse: [1e-300, -0.0, 0.011_8],
            },
            PackedContact {
                a: BodyRef::Stone(3),
                b: BodyRef::Sleeper(1),
                point: [0.5, 0.25, 0.125],
                impulse: [0.1, 0.2, 0.3],
            },
        ];
        let text = contacts_csv(&contacts);
        let path = Path::new("contacts.csv");
        assert_eq!(parse_contacts(path, &text).unwrap(), contacts);
        let cases = [
            (text.replace("stone 12", "stone x"), "line 2"),
            (text.replace("sleeper 1", "tine 1"), "line 3"),
            (text.replace(",0.5,", ",NaN,"), "line 3"),
            (text.replace(",0.5,", ","), "line 3"),
            (text.replace("impulse_z_Ns", "jz"), "line 1"),
        ];
        for (bad, line) in cases {
            let err = parse_contacts(path, &bad).unwrap_err().to_string();
            assert!(err.contains("contacts.csv") && err.contains(line), "{err}");
            assert_eq!(err.lines().count(), 1, "{err}");
        }
    }

    /// A stored point is found again whichever way round the restart numbers the
    /// pair: the impulse on each body is the stored one, in the point's own frame.
    #[test]
    fn warm_memory_matches_points_by_pair_and_position_either_way_round() {
        let stored = PackedContact {
            a: BodyRef::Stone(0),
            b: BodyRef::Sleeper(0),
            point: [0.1, 0.2, 0.3],
            impulse: [0.01, -0.02, 0.5],
        };
        let normal = Vector3::new(0.1, -0.2, 1.0).normalize();
        let point = |body_a: u32, body_b: u32, n: Vector3<f64>, dx: f64| ContactPoint {
            key: ContactKey {
                body_a,
                body_b,
                feature_a: 7,
                feature_b: 9,
            },
            point: Point3::new(0.1 + dx, 0.2, 0.3),
            normal: n,
            gap: 0.0,
            shift_b: Vector3::zeros(),
        };
        // The restart numbers the sleeper 5 and the stone 6 (sleepers first), so its
        // point runs from the sleeper (a) to the stone (b), the normal downwards.
        let index = |r: BodyRef| match r {
            BodyRef::Sleeper(0) => Some(5),
            BodyRef::Stone(0) => Some(6),
            _ => None,
        };
        for (a, b, n, sign) in [(5, 6, -normal, -1.0), (6, 5, normal, 1.0)] {
            let p = point(a, b, n, 0.0);
            let (memory, matched) = warm_memory(&[p], &[stored], index);
            assert_eq!(matched, 1);
            let local = memory.entries()[0].1;
            let [fn_, ft, fs] = local_frame(&n);
            let world = fn_ * local[0] + ft * local[1] + fs * local[2];
            let expected = sign * Vector3::from(stored.impulse);
            assert!((world - expected).norm() < 1e-15, "{world} vs {expected}");
            // The normal impulse is compressive, positive, in either numbering.
            assert!(local[0] > 0.0);
        }
        // A point of the same pair 1 mm away, or of another pair, takes nothing.
        let (_, matched) = warm_memory(&[point(5, 6, -normal, 1e-3)], &[stored], index);
        assert_eq!(matched, 0);
        let (_, matched) = warm_memory(&[point(5, 7, -normal, 0.0)], &[stored], index);
        assert_eq!(matched, 0);
    }
}

//! Boundary conditions of a QDEM run: fixed directions per node, group loads with a time
//! function, springs on a group's mean displacement, gravity. Node lists come from the
//! mesh's physical groups (see [`Constraints::fix_group`], [`NodalLoad::on_group`]); the
//! scene layer names them.

use crate::mesh::TetMesh;
use crate::{Error, Result};
use nalgebra::Vector3;

/// A set of Cartesian directions, as a bit mask (x = 1, y = 2, z = 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Directions(pub u8);

impl Directions {
    /// No direction.
    pub const NONE: Directions = Directions(0);
    /// x only.
    pub const X: Directions = Directions(1);
    /// y only.
    pub const Y: Directions = Directions(2);
    /// z only.
    pub const Z: Directions = Directions(4);
    /// All three (a fully fixed node).
    pub const ALL: Directions = Directions(7);

    /// The union of two sets.
    pub fn union(self, other: Directions) -> Directions {
        Directions(self.0 | other.0)
    }

    /// Whether direction `d` (0 = x, 1 = y, 2 = z) is in the set.
    pub fn contains(self, d: usize) -> bool {
        self.0 & (1 << d) != 0
    }
}

/// Nodes held at their current position in some directions (zero velocity there).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Constraints {
    fixed: Vec<(u32, Directions)>,
}

impl Constraints {
    /// No constraint.
    pub fn new() -> Self {
        Self::default()
    }

    /// Fixes `directions` of every node in `nodes` (adds to earlier constraints).
    pub fn fix(&mut self, nodes: &[u32], directions: Directions) -> &mut Self {
        self.fixed.extend(nodes.iter().map(|&n| (n, directions)));
        self
    }

    /// Fixes `directions` of the nodes of physical group `group` of `mesh`; the error
    /// names the mesh file, the missing group and the groups present.
    pub fn fix_group(
        &mut self,
        mesh: &TetMesh,
        group: &str,
        directions: Directions,
    ) -> Result<&mut Self> {
        mesh.require_groups(&[group])?;
        let nodes = &mesh.group(group).expect("checked above").nodes;
        Ok(self.fix(nodes, directions))
    }

    /// The per-node masks for `node_count` nodes; an error names an out-of-range node.
    pub(crate) fn masks(&self, node_count: usize) -> Result<Vec<u8>> {
        let mut masks = vec![0u8; node_count];
        for &(n, d) in &self.fixed {
            let m = masks.get_mut(n as usize).ok_or_else(|| {
                Error::Message(format!(
                    "QDEM constraint: node {n} does not exist (the model has {node_count} nodes)"
                ))
            })?;
            *m |= d.0;
        }
        Ok(masks)
    }
}

/// How a load's magnitude varies in time: a factor φ(t) multiplying its total force.
#[derive(Debug, Clone, PartialEq)]
pub enum TimeFunction {
    /// φ = 1.
    Constant,
    /// φ = t / t_ramp up to t_ramp, then 1 (the paper's 0 → 200 N in 1 s).
    Ramp {
        /// Duration of the ramp (s).
        t_ramp: f64,
    },
    /// φ = 1 before t0, 0 from t0 on (unloading: the creep-recovery test of eq. 14).
    SwitchOff {
        /// Switch-off time (s).
        t0: f64,
    },
    /// Piecewise linear through (`times[i]`, `values[i]`), constant beyond the ends.
    Table {
        /// Strictly increasing times (s).
        times: Vec<f64>,
        /// Factors at those times.
        values: Vec<f64>,
    },
}

impl TimeFunction {
    /// φ(t).
    pub fn value(&self, t: f64) -> f64 {
        match self {
            TimeFunction::Constant => 1.0,
            TimeFunction::Ramp { t_ramp } => {
                if t >= *t_ramp {
                    1.0
                } else {
                    (t / t_ramp).max(0.0)
                }
            }
            TimeFunction::SwitchOff { t0 } => {
                if t < *t0 {
                    1.0
                } else {
                    0.0
                }
            }
            TimeFunction::Table { times, values } => {
                let i = times.partition_point(|&ti| ti <= t);
                if i == 0 {
                    values[0]
                } else if i == times.len() {
                    values[times.len() - 1]
                } else {
                    let s = (t - times[i - 1]) / (times[i] - times[i - 1]);
                    values[i - 1] + s * (values[i] - values[i - 1])
                }
            }
        }
    }

    /// Checks the parameters; the error says what is wrong.
    pub fn validate(&self) -> Result<()> {
        let fail = |what: String| Err(Error::Message(format!("QDEM time function: {what}")));
        match self {
            TimeFunction::Constant => Ok(()),
            TimeFunction::Ramp { t_ramp } if !(t_ramp.is_finite() && *t_ramp > 0.0) => {
                fail(format!("ramp time t_ramp = {t_ramp} must be positive"))
            }
            TimeFunction::SwitchOff { t0 } if !t0.is_finite() => {
                fail(format!("switch-off time t0 = {t0} must be finite"))
            }
            TimeFunction::Table { times, values } => {
                if times.is_empty() || times.len() != values.len() {
                    return fail(format!(
                        "table needs as many times as values, at least one ({} times, {} values)",
                        times.len(),
                        values.len()
                    ));
                }
                if times.iter().chain(values).any(|v| !v.is_finite()) {
                    return fail("table has a non-finite entry".into());
                }
                if let Some(i) = times.windows(2).position(|w| w[1] <= w[0]) {
                    return fail(format!(
                        "table times must increase strictly (entry {} = {} after {})",
                        i + 1,
                        times[i + 1],
                        times[i]
                    ));
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }
}

/// A total force spread equally over a group's nodes: each node gets
/// `total_force / nodes.len() × φ(t)` (the paper's tip and top loads).
#[derive(Debug, Clone, PartialEq)]
pub struct NodalLoad {
    /// Loaded nodes (0-based, no duplicates).
    pub nodes: Vec<u32>,
    /// Total force over all the nodes (N).
    pub total_force: Vector3<f64>,
    /// The time factor φ(t).
    pub time_fn: TimeFunction,
}

impl NodalLoad {
    /// A load on the nodes of physical group `group` of `mesh`.
    pub fn on_group(
        mesh: &TetMesh,
        group: &str,
        total_force: Vector3<f64>,
        time_fn: TimeFunction,
    ) -> Result<Self> {
        mesh.require_groups(&[group])?;
        Ok(NodalLoad {
            nodes: mesh.group(group).expect("checked above").nodes.clone(),
            total_force,
            time_fn,
        })
    }

    pub(crate) fn validate(&self, index: usize, node_count: usize) -> Result<()> {
        let fail = |what: String| Err(Error::Message(format!("QDEM load {index}: {what}")));
        if let Err(what) = check_nodes(&self.nodes, node_count) {
            return fail(what);
        }
        if self.total_force.iter().any(|f| !f.is_finite()) {
            return fail("total force is not finite".into());
        }
        self.time_fn
            .validate()
            .map_err(|e| Error::Message(format!("QDEM load {index}: {e}")))
    }
}

/// A linear spring on the mean displacement of a node group along one direction: a
/// support that holds a group as a whole, not each node (the rails at a sleeper's rail
/// seat, which hold it along and across the track but let the seat's nodes deform).
///
/// With ū = e · (1/N) Σ_i (x_i − X_i) over the group's N nodes (X the reference
/// positions), the potential ½ k ū² gives every node the force −k ū e / N. The
/// integrator counts the potential with the strain energy, so the balance holds.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupSpring {
    /// The held nodes (0-based, no duplicates).
    pub nodes: Vec<u32>,
    /// The spring's direction e (a unit vector).
    pub direction: Vector3<f64>,
    /// k (N/m).
    pub stiffness: f64,
}

impl GroupSpring {
    pub(crate) fn validate(&self, index: usize, node_count: usize) -> Result<()> {
        let fail = |what: String| Err(Error::Message(format!("QDEM spring {index}: {what}")));
        if let Err(what) = check_nodes(&self.nodes, node_count) {
            return fail(what);
        }
        if !(self.stiffness.is_finite() && self.stiffness >= 0.0) {
            return fail(format!(
                "stiffness {} N/m must be finite and ≥ 0",
                self.stiffness
            ));
        }
        let unit = (self.direction.norm() - 1.0).abs() < 1e-9;
        if !unit {
            return fail(format!(
                "direction ({}, {}, {}) is not a unit vector",
                self.direction.x, self.direction.y, self.direction.z
            ));
        }
        Ok(())
    }
}

/// Checks a node list: not empty, every node below `node_count`, none twice.
fn check_nodes(nodes: &[u32], node_count: usize) -> std::result::Result<(), String> {
    if nodes.is_empty() {
        return Err("has no nodes".into());
    }
    if let Some(&n) = nodes.iter().find(|&&n| n as usize >= node_count) {
        return Err(format!(
            "node {n} does not exist (the model has {node_count} nodes)"
        ));
    }
    let mut sorted = nodes.to_vec();
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(format!("node {} is listed twice", w[0]));
    }
    Ok(())
}

/// Everything applied to a body from outside: constraints, loads, group springs and
/// gravity.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Boundary {
    /// Fixed directions.
    pub constraints: Constraints,
    /// Group loads.
    pub loads: Vec<NodalLoad>,
    /// Springs on groups' mean displacements.
    pub springs: Vec<GroupSpring>,
    /// Gravitational acceleration (m/s²), e.g. (0, 0, −9.81); zero for none.
    pub gravity: Vector3<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_functions() {
        assert_eq!(TimeFunction::Ramp { t_ramp: 2.0 }.value(1.0), 0.5);
        assert_eq!(TimeFunction::Ramp { t_ramp: 2.0 }.value(3.0), 1.0);
        assert_eq!(TimeFunction::SwitchOff { t0: 0.5 }.value(0.49), 1.0);
        assert_eq!(TimeFunction::SwitchOff { t0: 0.5 }.value(0.5), 0.0);
        let table = TimeFunction::Table {
            times: vec![0.0, 1.0, 2.0],
            values: vec![0.0, 1.0, 0.0],
        };
        assert_eq!(table.value(-1.0), 0.0);
        assert_eq!(table.value(0.5), 0.5);
        assert_eq!(table.value(1.5), 0.5);
        assert_eq!(table.value(9.0), 0.0);
        let bad = TimeFunction::Table {
            times: vec![0.0, 0.0],
            values: vec![0.0, 1.0],
        };
        assert!(bad.validate().unwrap_err().to_string().contains("increase"));
    }
}

//! Linear statics: K_ff u_f = f_f − K_fc u_c by sparse Cholesky on the reduced system.

use super::{seconds_since, FemSystem, PhaseTimes};
use crate::{Error, Result};
use faer::Mat;
use nalgebra::Vector3;
use std::time::Instant;

/// The result of a static solve.
#[derive(Debug, Clone)]
pub struct StaticSolution {
    /// Nodal displacement in m (prescribed values at fixed DOFs).
    pub displacement: Vec<Vector3<f64>>,
    /// Support reactions in N at the fixed DOFs (zero elsewhere): K u + springs − loads.
    pub reactions: Vec<Vector3<f64>>,
    /// Wall time per phase (this system's assembly and ordering included).
    pub timings: PhaseTimes,
}

impl FemSystem<'_> {
    /// Solves for nodal `loads` (N, one vector per node; components at fixed DOFs are
    /// carried by the supports and reported in the reactions).
    pub fn static_solve(&mut self, loads: &[Vector3<f64>]) -> Result<StaticSolution> {
        let node_count = self.model.nodes.len();
        if loads.len() != node_count {
            return Err(Error::Message(format!(
                "fem: {} nodal loads given for {node_count} nodes",
                loads.len()
            )));
        }
        if let Some(n) = loads
            .iter()
            .position(|f| !(f.x.is_finite() && f.y.is_finite() && f.z.is_finite()))
        {
            return Err(Error::Message(format!(
                "fem: the load at node {n} is not finite"
            )));
        }
        let mut times = self.setup_times;
        self.setup_times = PhaseTimes::default();
        // Right-hand side: loads on the free DOFs minus the pull of prescribed values.
        let start = Instant::now();
        let lifted = if self.dofs.has_nonzero {
            let prescribed = self.dofs.expand_homogeneous_fixed();
            Some(self.spring_and_elastic_forces(&prescribed))
        } else {
            None
        };
        let n = self.dofs.free_count();
        let mut rhs = Mat::<f64>::zeros(n, 1);
        for (r, &dof) in self.dofs.full.iter().enumerate() {
            let (node, c) = (dof as usize / 3, dof as usize % 3);
            let lift = lifted.as_ref().map_or(0.0, |f| f[node][c]);
            rhs[(r, 0)] = loads[node][c] - lift;
        }
        times.assembly_s += seconds_since(start);
        let factor = self.stiffness_factor(&mut times)?;
        let start = Instant::now();
        factor.solve_in_place(rhs.as_mut());
        times.solve_s += seconds_since(start);
        let displacement = self.dofs.expand(rhs.col_as_slice(0));
        let start = Instant::now();
        let forces = self.spring_and_elastic_forces(&displacement);
        let reactions = forces
            .iter()
            .zip(loads)
            .enumerate()
            .map(|(node, (f, load))| {
                Vector3::from_fn(|c, _| {
                    if self.dofs.reduced[3 * node + c] == super::dirichlet::FIXED {
                        f[c] - load[c]
                    } else {
                        0.0
                    }
                })
            })
            .collect();
        times.solve_s += seconds_since(start);
        Ok(StaticSolution {
            displacement,
            reactions,
            timings: times,
        })
    }

    /// K u plus the spring forces, per node, for a full displacement field.
    fn spring_and_elastic_forces(&self, displacement: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let mut forces = self.model.internal_forces(displacement);
        if let Some(springs) = &self.springs {
            for (node, block) in springs.iter() {
                forces[node as usize] += block * displacement[node as usize];
            }
        }
        forces
    }
}

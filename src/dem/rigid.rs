//! Rigid bodies (6 degrees of freedom) carrying vertex spheres: the cheap stand-in for a
//! QDEM stone far from the load (issue: "model no more than the scene needs").
//!
//! Integrated with the same kick–drift–kick as the QDEM nodes (seed 004 §2.4):
//! v_{n+½} = v_n + dt/2 (F_n/m + g), L_{n+½} = L_n + dt/2 τ_n (angular momentum in the
//! world frame), x_{n+1} = x_n + dt v_{n+½}, q_{n+1} = exp(dt ω_{n+½}) q_n with
//! ω_{n+½} = R_n I⁻¹ R_nᵀ L_{n+½}; then forces at n+1 and the second half kick. The
//! contact velocities are those of the half step, as the QDEM viscous stress.

use nalgebra::{Matrix3, Point3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Mass properties of a rigid body from its tetra (exact for a polyhedron).
#[derive(Debug, Clone, PartialEq)]
pub struct RigidShape {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the world at t = 0 (m).
    pub centre: [f64; 3],
    /// Principal moments of inertia (kg m²).
    pub principal_inertia: [f64; 3],
    /// Principal axes at t = 0 (columns), a rotation.
    pub axes: UnitQuaternion<f64>,
    /// Sphere centres in the principal frame (m).
    pub spheres: Vec<[f64; 3]>,
}

impl RigidShape {
    /// Mass properties of tetra `tets` over `nodes` at `density`, with spheres centred
    /// at `sphere_centres` (world, at t = 0). `None` for a body of no volume.
    pub fn from_tets(
        nodes: &[Point3<f64>],
        tets: &[[u32; 4]],
        density: f64,
        sphere_centres: &[Point3<f64>],
    ) -> Option<Self> {
        let mut volume = 0.0;
        let mut first = Vector3::zeros();
        for t in tets {
            let [a, b, c, d] = t.map(|i| nodes[i as usize].coords);
            let v = (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0;
            volume += v;
            first += v * (a + b + c + d) / 4.0;
        }
        if volume <= 0.0 {
            return None;
        }
        let centre = first / volume;
        // Second moments about the centre: ∫ r rᵀ dV over each tetra is
        // V/20 (Σ r_i r_iᵀ + (Σ r_i)(Σ r_i)ᵀ) with r_i the vertices relative to the centre.
        let mut second = Matrix3::zeros();
        for t in tets {
            let r = t.map(|i| nodes[i as usize].coords - centre);
            let v = (r[1] - r[0]).cross(&(r[2] - r[0])).dot(&(r[3] - r[0])) / 6.0;
            let sum = r[0] + r[1] + r[2] + r[3];
            let mut m = sum * sum.transpose();
            for ri in &r {
                m += ri * ri.transpose();
            }
            second += m * (v / 20.0);
        }
        let inertia = (Matrix3::identity() * second.trace() - second) * density;
        let eig = inertia.symmetric_eigen();
        let mut axes = eig.eigenvectors;
        if axes.determinant() < 0.0 {
            axes.column_mut(2).neg_mut();
        }
        let rotation = UnitQuaternion::from_matrix(&axes);
        let spheres = sphere_centres
            .iter()
            .map(|p| {
                let local = rotation.inverse_transform_vector(&(p.coords - centre));
                [local.x, local.y, local.z]
            })
            .collect();
        Some(RigidShape {
            mass: density * volume,
            centre: [centre.x, centre.y, centre.z],
            principal_inertia: [eig.eigenvalues[0], eig.eigenvalues[1], eig.eigenvalues[2]],
            axes: rotation,
            spheres,
        })
    }
}

/// The state of one rigid body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidState {
    /// Centre of mass (m).
    pub position: [f64; 3],
    /// Orientation of the principal frame `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Velocity of the centre (m/s).
    pub velocity: [f64; 3],
    /// Angular momentum in the world frame (kg m²/s).
    pub angular_momentum: [f64; 3],
    /// Contact force of the last evaluation (N).
    pub force: [f64; 3],
    /// Contact torque about the centre of the last evaluation (N m).
    pub torque: [f64; 3],
}

impl RigidState {
    /// At rest in the shape's initial placement.
    pub fn at_rest(shape: &RigidShape) -> Self {
        let q = shape.axes.quaternion();
        RigidState {
            position: shape.centre,
            orientation: [q.w, q.i, q.j, q.k],
            velocity: [0.0; 3],
            angular_momentum: [0.0; 3],
            force: [0.0; 3],
            torque: [0.0; 3],
        }
    }

    /// The orientation as a rotation.
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        let [w, x, y, z] = self.orientation;
        UnitQuaternion::new_normalize(nalgebra::Quaternion::new(w, x, y, z))
    }

    /// Angular velocity ω = R I⁻¹ Rᵀ L (rad/s).
    pub fn angular_velocity(&self, shape: &RigidShape) -> Vector3<f64> {
        let r = self.rotation();
        let local = r.inverse_transform_vector(&Vector3::from(self.angular_momentum));
        let w = Vector3::new(
            local.x / shape.principal_inertia[0],
            local.y / shape.principal_inertia[1],
            local.z / shape.principal_inertia[2],
        );
        r.transform_vector(&w)
    }

    /// Half kick with the stored force and torque, plus gravity `g` and a damping force
    /// −α m v and torque −α L (α = `damping` in 1/s, 0 for none: numerical damping for
    /// settling, as the QDEM nodes' mass-proportional damping). Returns the energy the
    /// damping took over the half step (J).
    pub fn kick(&mut self, shape: &RigidShape, g: [f64; 3], half_dt: f64, damping: f64) -> f64 {
        let mut taken = 0.0;
        let omega = if damping > 0.0 {
            self.angular_velocity(shape)
        } else {
            Vector3::zeros()
        };
        for d in 0..3 {
            let drag = damping * self.velocity[d];
            let spin = damping * self.angular_momentum[d];
            taken += half_dt * (shape.mass * drag * self.velocity[d] + spin * omega[d]);
            self.velocity[d] += half_dt * (self.force[d] / shape.mass + g[d] - drag);
            self.angular_momentum[d] += half_dt * (self.torque[d] - spin);
        }
        taken
    }

    /// Drift over `dt` with the current (half-step) velocities.
    pub fn drift(&mut self, shape: &RigidShape, dt: f64) {
        let w = self.angular_velocity(shape);
        for d in 0..3 {
            self.position[d] += dt * self.velocity[d];
        }
        let q = UnitQuaternion::from_scaled_axis(w * dt) * self.rotation();
        let q = q.quaternion();
        self.orientation = [q.w, q.i, q.j, q.k];
    }

    /// World position and velocity of sphere `k`, given the body's rotation matrix
    /// (from [`Self::rotation`]) and angular velocity (from [`Self::angular_velocity`]),
    /// computed once per body and step.
    pub fn sphere(
        &self,
        shape: &RigidShape,
        rotation: &Matrix3<f64>,
        omega: &Vector3<f64>,
        k: usize,
    ) -> ([f64; 3], [f64; 3]) {
        self.sphere_at(&shape.spheres[k], rotation, omega)
    }

    /// [`Self::sphere`] for a sphere centre `offset` in the principal frame (a copy of
    /// the shape's, as a step's compact table of touched spheres holds).
    pub fn sphere_at(
        &self,
        offset: &[f64; 3],
        rotation: &Matrix3<f64>,
        omega: &Vector3<f64>,
    ) -> ([f64; 3], [f64; 3]) {
        let r = rotation * Vector3::from(*offset);
        let v = Vector3::from(self.velocity) + omega.cross(&r);
        (
            [
                self.position[0] + r.x,
                self.position[1] + r.y,
                self.position[2] + r.z,
            ],
            [v.x, v.y, v.z],
        )
    }

    /// Kinetic energy ½ m v² + ½ ω·L (J).
    pub fn kinetic_energy(&self, shape: &RigidShape) -> f64 {
        let v = Vector3::from(self.velocity);
        0.5 * shape.mass * v.norm_squared()
            + 0.5
                * self
                    .angular_velocity(shape)
                    .dot(&Vector3::from(self.angular_momentum))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qdem::structured_box;

    #[test]
    fn a_box_has_the_textbook_mass_properties() {
        let (nodes, tets) = structured_box(Vector3::new(0.4, 0.2, 0.1), [4, 2, 2]);
        let s = RigidShape::from_tets(&nodes, &tets, 1000.0, &[nodes[0]]).unwrap();
        let m = 1000.0 * 0.4 * 0.2 * 0.1;
        assert!((s.mass / m - 1.0).abs() < 1e-12);
        let mut i = s.principal_inertia;
        i.sort_by(f64::total_cmp);
        let expect = [
            m / 12.0 * (0.04 + 0.01),
            m / 12.0 * (0.16 + 0.01),
            m / 12.0 * (0.16 + 0.04),
        ];
        for k in 0..3 {
            assert!((i[k] / expect[k] - 1.0).abs() < 1e-10, "{i:?} {expect:?}");
        }
        assert!((s.centre[0] - 0.2).abs() < 1e-12 && (s.centre[2] - 0.05).abs() < 1e-12);
    }

    #[test]
    fn a_free_spin_keeps_its_angular_momentum_and_energy() {
        let (nodes, tets) = structured_box(Vector3::new(0.4, 0.2, 0.1), [2, 1, 1]);
        let s = RigidShape::from_tets(&nodes, &tets, 1000.0, &[nodes[0]]).unwrap();
        let mut st = RigidState::at_rest(&s);
        st.angular_momentum = [0.01, 0.002, 0.0];
        let e0 = st.kinetic_energy(&s);
        for _ in 0..1000 {
            st.kick(&s, [0.0; 3], 5e-5, 0.0);
            st.drift(&s, 1e-4);
            st.kick(&s, [0.0; 3], 5e-5, 0.0);
        }
        assert_eq!(st.angular_momentum, [0.01, 0.002, 0.0]);
        assert!((st.kinetic_energy(&s) / e0 - 1.0).abs() < 1e-3);
    }
}

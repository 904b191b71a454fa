//! Rigid bodies of the NSCD engine: convex polyhedra with exact mass properties, state
//! in the principal frame, and bodies that move by prescription (driven) or not at all
//! (static).
//!
//! A body's frame has its origin at the mass centre and its axes along the principal
//! axes of inertia, so M = diag(m, m, m, I₁, I₂, I₃) (seed 000 §2.1.1: "translational
//! velocities and rotation rates in the inertia basis"). The world pose is the position
//! of the mass centre and a unit quaternion.

use std::sync::Arc;

use nalgebra::{
    Isometry3, Matrix3, Point3, SymmetricEigen, Translation3, Unit, UnitQuaternion, Vector3,
};

use super::motion::VelocityTable;
use crate::contact::{Collider, ConvexShape};
use crate::geometry::{convex_hull, mass_properties};
use crate::{Error, Result};

/// The geometry of a body in its principal frame.
#[derive(Debug, Clone)]
pub struct BodyShape {
    /// Hull vertices (principal frame, m).
    pub vertices: Vec<Point3<f64>>,
    /// Outward hull triangles (0-based into `vertices`).
    pub triangles: Vec<[u32; 3]>,
    /// Volume (m³); zero for a half-space.
    pub volume: f64,
    /// Principal moments of inertia per unit density (m⁵), ascending.
    pub unit_inertia: Vector3<f64>,
    /// What contact detection sees.
    pub collider: Collider,
}

/// A convex polyhedral shape and where its principal frame lies in the input frame.
#[derive(Debug, Clone)]
pub struct PrincipalShape {
    /// The shape in its principal frame.
    pub shape: BodyShape,
    /// The principal frame in the input coordinates: input point = pose · local point.
    pub pose: Isometry3<f64>,
}

impl BodyShape {
    /// The convex hull of `points` in its principal frame (exact mass properties by
    /// polyhedral integration of the hull). `what` names the input in errors.
    pub fn convex_hull(points: &[Point3<f64>], what: &str) -> Result<PrincipalShape> {
        let (vertices, triangles) =
            convex_hull(points).map_err(|e| Error::Message(format!("{what}: {e}")))?;
        let mass = mass_properties(&vertices, &triangles);
        if !(mass.volume > 0.0 && mass.volume.is_finite()) {
            return Err(Error::Message(format!(
                "{what}: the convex hull has volume {} (degenerate)",
                mass.volume
            )));
        }
        let eigen = SymmetricEigen::new(mass.inertia);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
        let mut axes = Matrix3::from_columns(&[
            eigen.eigenvectors.column(order[0]).into_owned(),
            eigen.eigenvectors.column(order[1]).into_owned(),
            eigen.eigenvectors.column(order[2]).into_owned(),
        ]);
        if axes.determinant() < 0.0 {
            axes.set_column(2, &(-axes.column(2)));
        }
        let rotation = UnitQuaternion::from_matrix(&axes);
        let pose = Isometry3::from_parts(Translation3::from(mass.centroid.coords), rotation);
        let local: Vec<Point3<f64>> = vertices
            .iter()
            .map(|p| pose.inverse_transform_point(p))
            .collect();
        let unit_inertia = Vector3::new(
            eigen.eigenvalues[order[0]],
            eigen.eigenvalues[order[1]],
            eigen.eigenvalues[order[2]],
        );
        let collider = ConvexShape::from_points(&local)
            .ok_or_else(|| Error::Message(format!("{what}: parry cannot build its convex hull")))?;
        Ok(PrincipalShape {
            shape: BodyShape {
                vertices: local,
                triangles,
                volume: mass.volume,
                unit_inertia,
                collider: Collider::Convex(collider),
            },
            pose,
        })
    }

    /// A box of full edge lengths `size`, centred, axes along x, y, z.
    pub fn cuboid(size: Vector3<f64>) -> Result<BodyShape> {
        let h = 0.5 * size;
        let mut points = Vec::with_capacity(8);
        for k in 0..8 {
            points.push(Point3::new(
                if k & 1 == 0 { -h.x } else { h.x },
                if k & 2 == 0 { -h.y } else { h.y },
                if k & 4 == 0 { -h.z } else { h.z },
            ));
        }
        // The box's own axes are principal (an eigen solver may permute them for a cube,
        // so the frame is not taken from one).
        let (vertices, triangles) = convex_hull(&points)?;
        let mass = mass_properties(&vertices, &triangles);
        let unit_inertia = Vector3::new(
            mass.inertia[(0, 0)],
            mass.inertia[(1, 1)],
            mass.inertia[(2, 2)],
        );
        let collider = ConvexShape::from_points(&vertices)
            .ok_or_else(|| Error::Message("box: parry cannot build its convex hull".into()))?;
        Ok(BodyShape {
            vertices,
            triangles,
            volume: mass.volume,
            unit_inertia,
            collider: Collider::Convex(collider),
        })
    }

    /// The half-space below the plane through the origin with outward normal `normal`.
    pub fn half_space(normal: Unit<Vector3<f64>>) -> BodyShape {
        BodyShape {
            vertices: Vec::new(),
            triangles: Vec::new(),
            volume: 0.0,
            unit_inertia: Vector3::zeros(),
            collider: Collider::HalfSpace(normal),
        }
    }
}

impl PrincipalShape {
    /// Spheres of `diameter` (m) at every surface node of `mesh` (scaled by `scale`,
    /// then placed by `input_from_mesh` into the input coordinates of
    /// [`BodyShape::convex_hull`]) as the contact shape (seed 004's QDEM contact
    /// spheres); mass and inertia stay the hull's.
    pub fn with_vertex_spheres(
        &mut self,
        mesh: &crate::mesh::TetMesh,
        input_from_mesh: &Isometry3<f64>,
        scale: f64,
        diameter: f64,
    ) {
        let local = self.pose.inverse() * input_from_mesh;
        let centres = mesh
            .surface_nodes()
            .iter()
            .map(|&i| local * (mesh.nodes[i as usize] * scale))
            .collect();
        if let Some(spheres) = self.shape.collider.with_spheres(centres, 0.5 * diameter) {
            self.shape.collider = spheres;
        }
    }
}

impl BodyShape {
    /// The largest distance of a point of the body from the frame's origin: of a vertex,
    /// plus the collider's rounding (zero for a half-space).
    pub fn bounding_radius(&self) -> f64 {
        self.vertices
            .iter()
            .map(|p| p.coords.norm())
            .fold(0.0, f64::max)
            + self.collider.round()
    }
}

/// A prescribed motion: a constant velocity, plus a sinusoidal oscillation, plus a
/// piecewise-linear velocity table (each part optional).
///
/// The table is shared (reference-counted) by the pieces of one driven body.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Prescribed {
    /// Constant translational velocity (m/s).
    pub velocity: Vector3<f64>,
    /// Amplitude of the oscillating displacement (m); zero for none.
    pub amplitude: Vector3<f64>,
    /// Frequency of the oscillation (Hz).
    pub frequency: f64,
    /// A piecewise-linear velocity added to the rest (m/s).
    pub table: Option<Arc<VelocityTable>>,
}

impl Prescribed {
    /// `self` with the velocity table `table`.
    pub fn with_table(mut self, table: VelocityTable) -> Self {
        self.table = Some(Arc::new(table));
        self
    }

    /// The velocity at time `t`: `v + 2πf A cos(2πf t) + table(t)`.
    pub fn velocity_at(&self, t: f64) -> Vector3<f64> {
        let omega = std::f64::consts::TAU * self.frequency;
        let table = self
            .table
            .as_ref()
            .map_or(Vector3::zeros(), |v| v.velocity_at(t));
        self.velocity + self.amplitude * omega * (omega * t).cos() + table
    }

    /// The exact displacement from `t0` to `t1`:
    /// `v (t1 − t0) + A (sin 2πf t1 − sin 2πf t0) + ∫ table`.
    pub fn displacement(&self, t0: f64, t1: f64) -> Vector3<f64> {
        let omega = std::f64::consts::TAU * self.frequency;
        let table = self
            .table
            .as_ref()
            .map_or(Vector3::zeros(), |v| v.displacement(t0, t1));
        self.velocity * (t1 - t0)
            + self.amplitude * ((omega * t1).sin() - (omega * t0).sin())
            + table
    }

    /// The oscillating part of the displacement from t = 0: `A sin 2πf t`.
    pub fn oscillation_at(&self, t: f64) -> Vector3<f64> {
        self.amplitude * (std::f64::consts::TAU * self.frequency * t).sin()
    }

    /// Whether it never moves (no velocity, no oscillation, no table).
    pub fn is_rest(&self) -> bool {
        self.velocity == Vector3::zeros()
            && (self.amplitude == Vector3::zeros() || self.frequency == 0.0)
            && self.table.is_none()
    }
}

/// A body hung on a driven anchor by a linear spring and dashpot (translation only):
/// a tamping tine on its arm (its pieces one group, [`Spring::group`]). The drive moves
/// the anchor as prescribed; the body follows through the spring, so a jam meets a
/// force bounded by the spring's stretch instead of whatever a rigid drive needs to go
/// through it.
///
/// The force on the body is `K (a − x) + C (v_a − v)` with `a` the anchor and `v_a` its
/// velocity; the step integrates it with the θ-method, implicitly (Moreau–Jean for
/// linear forces), so any stiffness is stable.
#[derive(Debug, Clone, PartialEq)]
pub struct Spring {
    /// How the anchor moves.
    pub drive: Prescribed,
    /// Where the anchor is at the start of the step (m): where the mass centre would
    /// rest without load. The owner of the drive may set it step by step
    /// ([`super::tamping::TampingMonitor::actuate`]); the step advances it otherwise.
    pub anchor: Vector3<f64>,
    /// The anchor at t = 0 (m).
    pub rest: Vector3<f64>,
    /// Stiffness K (N/m), the same along every axis: the whole tool's.
    pub stiffness: f64,
    /// Damping C (N·s/m): the whole tool's.
    pub damping: f64,
    /// The sprung bodies of one group are the pieces of one tool: they move as one
    /// rigid body of their summed mass, held by the spring of the group's first body
    /// (whose anchor, stiffness and damping count), and do not touch each other.
    pub group: u32,
}

impl Spring {
    /// The anchor's θ-averages over the step from `time` to `time + h`: its position
    /// `(1 − θ) a_i + θ a_{i+1}` and its velocity `(1 − θ) v_a,i + θ v_a,i+1`.
    pub fn anchor_theta(&self, time: f64, h: f64, theta: f64) -> (Vector3<f64>, Vector3<f64>) {
        let drive = &self.drive;
        (
            self.anchor + theta * drive.displacement(time, time + h),
            (1.0 - theta) * drive.velocity_at(time) + theta * drive.velocity_at(time + h),
        )
    }
}

/// How a body moves.
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// By the dynamics (gravity and contacts).
    Dynamic,
    /// By prescription, whatever the contacts.
    Driven(Prescribed),
    /// By the dynamics, held to a driven anchor by a spring; it does not turn.
    Sprung(Spring),
    /// Not at all.
    Static,
}

/// `ωᵀ I ω` about principal axes, skipping the axes of infinite inertia (held, so
/// ω = 0 about them; ∞ · 0 would be NaN).
pub fn rotational_energy(inertia: &Vector3<f64>, w: &Vector3<f64>) -> f64 {
    (0..3)
        .filter(|&k| inertia[k].is_finite())
        .map(|k| inertia[k] * w[k] * w[k])
        .sum()
}

/// One rigid body and its state.
#[derive(Debug, Clone)]
pub struct Body {
    /// A name for reports.
    pub name: String,
    /// Geometry in the principal frame (shared between copies of a shape).
    pub shape: Arc<BodyShape>,
    /// Material index (friction per pair of materials).
    pub material: u32,
    /// How it moves.
    pub motion: Motion,
    /// Mass (kg); infinite for driven and static bodies.
    pub mass: f64,
    /// Principal moments of inertia (kg·m²).
    pub inertia: Vector3<f64>,
    /// Position of the mass centre (m).
    pub position: Vector3<f64>,
    /// Orientation of the principal frame.
    pub orientation: UnitQuaternion<f64>,
    /// Velocity of the mass centre (m/s, world).
    pub velocity: Vector3<f64>,
    /// Angular velocity (rad/s) in the principal frame.
    pub angular_velocity: Vector3<f64>,
}

impl Body {
    /// A dynamic body of `shape` and `density` at `pose` (of its principal frame).
    pub fn dynamic(
        name: &str,
        shape: Arc<BodyShape>,
        density: f64,
        material: u32,
        pose: Isometry3<f64>,
    ) -> Body {
        let mass = density * shape.volume;
        let inertia = density * shape.unit_inertia;
        Body {
            name: name.to_string(),
            shape,
            material,
            motion: Motion::Dynamic,
            mass,
            inertia,
            position: pose.translation.vector,
            orientation: pose.rotation,
            velocity: Vector3::zeros(),
            angular_velocity: Vector3::zeros(),
        }
    }

    /// A static or driven body (infinite mass).
    pub fn fixed(
        name: &str,
        shape: Arc<BodyShape>,
        material: u32,
        pose: Isometry3<f64>,
        motion: Motion,
    ) -> Body {
        Body {
            name: name.to_string(),
            shape,
            material,
            motion,
            mass: f64::INFINITY,
            inertia: Vector3::repeat(f64::INFINITY),
            position: pose.translation.vector,
            orientation: pose.rotation,
            velocity: Vector3::zeros(),
            angular_velocity: Vector3::zeros(),
        }
    }

    /// `self` without yaw: infinite inertia about the principal axis nearest the world
    /// vertical, so contacts can tilt it but not turn it in plan. A sleeper is held
    /// square to the track by its rails and fastenings; left free, a lowered sleeper
    /// turns on the stones it first lands on (11° on the quick bed).
    pub fn without_yaw(mut self) -> Body {
        let up = self.orientation.inverse() * Vector3::z();
        let axis = (0..3)
            .max_by(|&a, &b| up[a].abs().total_cmp(&up[b].abs()))
            .expect("three axes");
        self.inertia[axis] = f64::INFINITY;
        self.angular_velocity[axis] = 0.0;
        self
    }

    /// The body with infinite inertia about every axis: it translates but does not
    /// turn (a sleeper held level by its rails while it is lowered onto the bed).
    pub fn translation_only(mut self) -> Body {
        self.inertia = Vector3::repeat(f64::INFINITY);
        self.angular_velocity = Vector3::zeros();
        self
    }

    /// Whether the dynamics moves it (a free body: a stone, a lowered sleeper).
    pub fn is_dynamic(&self) -> bool {
        self.motion == Motion::Dynamic
    }

    /// Whether contacts can move it: dynamic or sprung.
    pub fn is_movable(&self) -> bool {
        matches!(self.motion, Motion::Dynamic | Motion::Sprung(_))
    }

    /// The spring group of a sprung body.
    pub fn spring_group(&self) -> Option<u32> {
        match &self.motion {
            Motion::Sprung(s) => Some(s.group),
            _ => None,
        }
    }

    /// The world pose of the principal frame.
    pub fn pose(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.position), self.orientation)
    }

    /// 1/m (zero unless dynamic; a sprung body's effective mass depends on the step,
    /// [`Spring`]).
    pub fn inverse_mass(&self) -> f64 {
        if self.is_dynamic() {
            1.0 / self.mass
        } else {
            0.0
        }
    }

    /// The world inverse inertia R diag(1/I) Rᵀ (zero unless dynamic).
    pub fn inverse_inertia_world(&self) -> Matrix3<f64> {
        if !self.is_dynamic() {
            return Matrix3::zeros();
        }
        let r = self.orientation.to_rotation_matrix();
        let d = Matrix3::from_diagonal(&self.inertia.map(|i| 1.0 / i));
        r.matrix() * d * r.matrix().transpose()
    }

    /// The angular velocity in world axes.
    pub fn angular_velocity_world(&self) -> Vector3<f64> {
        self.orientation * self.angular_velocity
    }

    /// Kinetic energy ½ m v² of a sprung body (J); zero for any other.
    pub fn sprung_kinetic_energy(&self) -> f64 {
        match self.motion {
            Motion::Sprung(_) => 0.5 * self.mass * self.velocity.norm_squared(),
            _ => 0.0,
        }
    }

    /// Kinetic energy ½ m v² + ½ ωᵀ I ω (J); zero unless dynamic.
    pub fn kinetic_energy(&self) -> f64 {
        if !self.is_dynamic() {
            return 0.0;
        }
        0.5 * self.mass * self.velocity.norm_squared()
            + 0.5 * rotational_energy(&self.inertia, &self.angular_velocity)
    }

    /// An upper bound on the speed of any point of the body, |v| + |ω| r with r its
    /// bounding radius (m/s): how far its points can move in a step (the detection
    /// reach) and what a settled bed holds under a limit (`ballast-pack`).
    pub fn point_speed_bound(&self) -> f64 {
        self.velocity.norm() + self.angular_velocity.norm() * self.shape.bounding_radius()
    }

    /// The hull vertices in world coordinates.
    pub fn world_vertices(&self) -> Vec<Point3<f64>> {
        let pose = self.pose();
        self.shape.vertices.iter().map(|p| pose * p).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_mass_properties_are_exact() {
        let shape = BodyShape::cuboid(Vector3::new(0.2, 0.2, 0.2)).unwrap();
        assert!((shape.volume - 0.008).abs() < 1e-15);
        // I = m a² / 6 per unit density: V a² / 6.
        for k in 0..3 {
            assert!((shape.unit_inertia[k] - 0.008 * 0.04 / 6.0).abs() < 1e-16);
        }
        let body = Body::dynamic("c", Arc::new(shape), 2500.0, 0, Isometry3::identity());
        assert!((body.mass - 20.0).abs() < 1e-12);
        assert!((body.inertia.x - 20.0 * 0.04 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn principal_frame_of_a_rotated_box() {
        // A 0.4 × 0.2 × 0.1 box rotated and shifted: its principal frame recovers the
        // centre and the moments m(b² + c²)/12 … in ascending order.
        let rotation = UnitQuaternion::from_euler_angles(0.3, -0.7, 1.1);
        let shift = Vector3::new(1.0, -2.0, 0.5);
        let mut points = Vec::new();
        for k in 0..8 {
            let p = Vector3::new(
                if k & 1 == 0 { -0.2 } else { 0.2 },
                if k & 2 == 0 { -0.1 } else { 0.1 },
                if k & 4 == 0 { -0.05 } else { 0.05 },
            );
            points.push(Point3::from(rotation * p + shift));
        }
        let principal = BodyShape::convex_hull(&points, "box").unwrap();
        let v = 0.4 * 0.2 * 0.1;
        let expect = [
            v * (0.2f64.powi(2) + 0.1f64.powi(2)) / 12.0,
            v * (0.4f64.powi(2) + 0.1f64.powi(2)) / 12.0,
            v * (0.4f64.powi(2) + 0.2f64.powi(2)) / 12.0,
        ];
        for (k, value) in expect.iter().enumerate() {
            assert!((principal.shape.unit_inertia[k] - value).abs() < 1e-12 * value);
        }
        assert!((principal.pose.translation.vector - shift).norm() < 1e-12);
        // Local vertices map back onto the input.
        for p in &principal.shape.vertices {
            let q = principal.pose * p;
            assert!(points.iter().any(|x| (x - q).norm() < 1e-12));
        }
    }
}

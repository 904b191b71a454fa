//! Prescribed motions of driven bodies: a piecewise-linear velocity table (inline in the
//! scene or from a CSV file) and its exact integral, and the convex pieces of a driven
//! tetra mesh.
//!
//! A table `t_0 < t_1 < … < t_n`, `v_0 … v_n` gives `v(t)` by linear interpolation,
//! holding `v_0` before `t_0` and `v_n` after `t_n`. Its integral is exact (trapezoids
//! between breakpoints), so the displacement a run should produce can be checked; with
//! θ = 0.5 the step's position update `h((1 − θ) v_i + θ v_{i+1})` reproduces it exactly
//! when the breakpoints fall on step boundaries.

use std::path::Path;

use nalgebra::{Point3, Vector3};

use crate::mesh::TetMesh;

/// A piecewise-linear velocity as a function of time.
#[derive(Debug, Clone, PartialEq)]
pub struct VelocityTable {
    times: Vec<f64>,
    values: Vec<Vector3<f64>>,
}

impl VelocityTable {
    /// A table of `times` (s, strictly increasing, at least one) and `values` (m/s, one
    /// per time); the error is the reason, without a key.
    pub fn new(times: Vec<f64>, values: Vec<Vector3<f64>>) -> Result<Self, String> {
        if times.is_empty() {
            return Err("the table needs at least one time".into());
        }
        if times.len() != values.len() {
            return Err(format!(
                "{} times but {} values (one [vx, vy, vz] per time)",
                times.len(),
                values.len()
            ));
        }
        if let Some(k) = times.iter().position(|t| !t.is_finite()) {
            return Err(format!("time {k} is not finite"));
        }
        if let Some(k) = values.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
            return Err(format!("value {k} is not finite"));
        }
        if let Some(k) = (1..times.len()).find(|&k| times[k] <= times[k - 1]) {
            return Err(format!(
                "times must increase strictly: time {k} ({} s) follows {} s",
                times[k],
                times[k - 1]
            ));
        }
        Ok(VelocityTable { times, values })
    }

    /// Reads a CSV table: one row `t, vx, vy, vz` per breakpoint (SI units: s, m/s);
    /// blank lines, `#` comments and a first line that is not numbers (a header) are
    /// skipped. The error names the line.
    pub fn read_csv(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse_csv(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// [`Self::read_csv`] on text in memory.
    pub fn parse_csv(text: &str) -> Result<Self, String> {
        let (mut times, mut values) = (Vec::new(), Vec::new());
        for (index, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let numbers: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
            match numbers {
                Ok(n) if n.len() == 4 => {
                    times.push(n[0]);
                    values.push(Vector3::new(n[1], n[2], n[3]));
                }
                Ok(n) => {
                    return Err(format!(
                        "line {}: {} numbers, expected 4 (t, vx, vy, vz)",
                        index + 1,
                        n.len()
                    ))
                }
                Err(_) if times.is_empty() && index == first_line(text) => continue,
                Err(_) => {
                    return Err(format!(
                        "line {}: \"{line}\" is not four numbers t, vx, vy, vz",
                        index + 1
                    ))
                }
            }
        }
        Self::new(times, values)
    }

    /// The breakpoint times (s).
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// The velocity at time `t`: linear between breakpoints, held outside.
    pub fn velocity_at(&self, t: f64) -> Vector3<f64> {
        let n = self.times.len();
        if t <= self.times[0] {
            return self.values[0];
        }
        if t >= self.times[n - 1] {
            return self.values[n - 1];
        }
        // First breakpoint after t.
        let k = self.times.partition_point(|&x| x <= t);
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let s = (t - t0) / (t1 - t0);
        self.values[k - 1] * (1.0 - s) + self.values[k] * s
    }

    /// The exact integral of the velocity from `t0` to `t1` (m).
    pub fn displacement(&self, t0: f64, t1: f64) -> Vector3<f64> {
        if t1 < t0 {
            return -self.displacement(t1, t0);
        }
        // Integrate over [t0, t1] cut at every breakpoint inside: v is linear on each part.
        let mut cuts = vec![t0];
        cuts.extend(self.times.iter().copied().filter(|&t| t > t0 && t < t1));
        cuts.push(t1);
        cuts.windows(2)
            .map(|w| 0.5 * (w[1] - w[0]) * (self.velocity_at(w[0]) + self.velocity_at(w[1])))
            .sum()
    }
}

/// The index of the first non-blank, non-comment line.
fn first_line(text: &str) -> usize {
    text.lines()
        .position(|l| !l.split('#').next().unwrap_or("").trim().is_empty())
        .unwrap_or(0)
}

/// How a driven mesh is cut into convex pieces.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Pieces {
    /// One piece per physical volume group; the whole mesh when it has at most one.
    #[default]
    Volumes,
    /// One piece: the convex hull of the whole mesh.
    Hull,
    /// One piece per named physical group (any dimension: the hull of its nodes).
    Groups(Vec<String>),
}

/// A convex piece's name and the points whose hull it is.
pub type PiecePoints = (String, Vec<Point3<f64>>);

/// The node sets of a mesh's convex pieces, each with a name (the group's, or `hull`).
/// The error is the reason, naming the missing group and the groups the mesh has.
pub fn mesh_pieces(mesh: &TetMesh, pieces: &Pieces) -> Result<Vec<PiecePoints>, String> {
    let nodes = |indices: &[u32]| -> Vec<Point3<f64>> {
        indices.iter().map(|&i| mesh.nodes[i as usize]).collect()
    };
    let whole = || {
        let mut boundary: Vec<u32> = mesh.boundary.iter().flatten().copied().collect();
        boundary.sort_unstable();
        boundary.dedup();
        vec![("hull".to_string(), nodes(&boundary))]
    };
    match pieces {
        Pieces::Hull => Ok(whole()),
        Pieces::Volumes => {
            let volumes: Vec<_> = mesh.groups.iter().filter(|g| g.dim == 3).collect();
            if volumes.len() <= 1 {
                return Ok(whole());
            }
            Ok(volumes
                .iter()
                .map(|g| (g.name.clone(), nodes(&g.nodes)))
                .collect())
        }
        Pieces::Groups(names) => {
            if names.is_empty() {
                return Err("give at least one physical group".into());
            }
            let mut out = Vec::with_capacity(names.len());
            for name in names {
                let Some(group) = mesh.group(name) else {
                    let present: Vec<&str> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
                    return Err(format!(
                        "physical group \"{name}\" is not in {} (it has: {})",
                        mesh.source.display(),
                        if present.is_empty() {
                            "no groups".to_string()
                        } else {
                            present.join(", ")
                        }
                    ));
                };
                out.push((name.clone(), nodes(&group.nodes)));
            }
            Ok(out)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::PhysicalGroup;

    fn tamping_cycle() -> VelocityTable {
        // Penetrate at 1 m/s for 0.1 s, stop, squeeze at 0.05 m/s, withdraw.
        VelocityTable::new(
            vec![0.0, 0.02, 0.1, 0.12, 0.3, 0.32, 0.5],
            vec![
                Vector3::zeros(),
                Vector3::new(0.0, 0.0, -1.0),
                Vector3::new(0.0, 0.0, -1.0),
                Vector3::new(0.05, 0.0, 0.0),
                Vector3::new(0.05, 0.0, 0.0),
                Vector3::new(0.0, 0.0, 1.0),
                Vector3::new(0.0, 0.0, 1.0),
            ],
        )
        .unwrap()
    }

    #[test]
    fn table_interpolates_and_holds_its_ends() {
        let table = tamping_cycle();
        assert_eq!(table.velocity_at(-1.0), Vector3::zeros());
        assert!((table.velocity_at(0.01) - Vector3::new(0.0, 0.0, -0.5)).norm() < 1e-15);
        assert_eq!(table.velocity_at(0.05), Vector3::new(0.0, 0.0, -1.0));
        assert!((table.velocity_at(0.11) - Vector3::new(0.025, 0.0, -0.5)).norm() < 1e-14);
        assert_eq!(table.velocity_at(0.1), Vector3::new(0.0, 0.0, -1.0));
        assert_eq!(table.velocity_at(7.0), Vector3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn table_integral_is_exact_and_matches_the_theta_update() {
        let table = tamping_cycle();
        // Down: 0.5 × 0.02 × 1 + 0.08 × 1 + 0.5 × 0.02 × 1 = 0.1 m; up from 0.3 s:
        // 0.5 × 0.02 + 0.18 = 0.19 m; squeeze: 0.5 × 0.02 × 0.05 × 2 + 0.18 × 0.05.
        let d = table.displacement(0.0, 0.5);
        assert!((d.z - (-0.1 + 0.19)).abs() < 1e-15, "{d}");
        assert!((d.x - (0.001 + 0.009)).abs() < 1e-15, "{d}");
        // Additive over sub-intervals, antisymmetric.
        let split = table.displacement(0.0, 0.137) + table.displacement(0.137, 0.5);
        assert!((split - d).norm() < 1e-15);
        assert_eq!(table.displacement(0.3, 0.1), -table.displacement(0.1, 0.3));
        // The θ = 0.5 update on steps of 1 ms (breakpoints on step boundaries) sums to the
        // exact integral; after the table, the last value is held.
        let h = 1e-3;
        let mut x = Vector3::zeros();
        for k in 0..600 {
            let (t0, t1) = (k as f64 * h, (k + 1) as f64 * h);
            x += h * 0.5 * (table.velocity_at(t0) + table.velocity_at(t1));
        }
        let exact = table.displacement(0.0, 0.6);
        assert!((x - exact).norm() < 1e-14, "{x} vs {exact}");
        assert!((exact - d - Vector3::new(0.0, 0.0, 0.1)).norm() < 1e-15);
    }

    #[test]
    fn bad_tables_are_refused_with_the_reason() {
        let v = Vector3::zeros();
        assert!(VelocityTable::new(vec![], vec![])
            .unwrap_err()
            .contains("at least one"));
        assert!(VelocityTable::new(vec![0.0, 1.0], vec![v])
            .unwrap_err()
            .contains("2 times but 1 values"));
        assert!(VelocityTable::new(vec![0.0, 0.0], vec![v, v])
            .unwrap_err()
            .contains("increase strictly: time 1"));
        assert!(VelocityTable::new(vec![f64::NAN], vec![v])
            .unwrap_err()
            .contains("not finite"));
    }

    #[test]
    fn csv_tables_skip_a_header_and_name_bad_lines() {
        let table =
            VelocityTable::parse_csv("time_s,vx,vy,vz\n# ramp\n0, 0, 0, 0\n0.1, 0.2, 0, 0\n\n")
                .unwrap();
        assert_eq!(table.times(), [0.0, 0.1]);
        assert!((table.velocity_at(0.05).x - 0.1).abs() < 1e-15);
        assert!(VelocityTable::parse_csv("0,0,0,0\n1,2,3\n")
            .unwrap_err()
            .starts_with("line 2: 3 numbers"));
        assert!(VelocityTable::parse_csv("0,0,0,0\nt,1,2,3\n")
            .unwrap_err()
            .starts_with("line 2: \"t,1,2,3\""));
    }

    /// Two unit cubes side by side (x in [0, 1] and [1, 2]), six tetrahedra each, as two
    /// physical volumes plus a surface group on the second cube's top face.
    fn two_cubes() -> TetMesh {
        let mut nodes = Vec::new();
        for i in 0..3 {
            for j in 0..2 {
                for k in 0..2 {
                    nodes.push(Point3::new(i as f64, j as f64, k as f64));
                }
            }
        }
        let id = |i: u32, j: u32, k: u32| i * 4 + j * 2 + k;
        let mut tets = Vec::new();
        for c in 0..2u32 {
            // Kuhn's six tetrahedra of a cube along the diagonal (0,0,0)–(1,1,1).
            let corner = |b: u32| id(c + (b & 1), (b >> 1) & 1, (b >> 2) & 1);
            for path in [
                [1, 2, 4],
                [1, 4, 2],
                [2, 1, 4],
                [2, 4, 1],
                [4, 1, 2],
                [4, 2, 1],
            ] {
                let mut b = 0u32;
                let mut tet = [corner(0), 0, 0, 0];
                for (s, step) in path.iter().enumerate() {
                    b |= step;
                    tet[s + 1] = corner(b);
                }
                let p: Vec<Point3<f64>> = tet.iter().map(|&n| nodes[n as usize]).collect();
                let volume = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0]));
                if volume < 0.0 {
                    tet.swap(2, 3);
                }
                tets.push(tet);
            }
        }
        let group = |name: &str, dim: u8, tet_range: std::ops::Range<u32>, node_ids: Vec<u32>| {
            PhysicalGroup {
                name: name.into(),
                dim,
                tag: 1,
                nodes: node_ids,
                triangles: Vec::new(),
                tets: tet_range.collect(),
            }
        };
        let left: Vec<u32> = (0..8).collect();
        let right: Vec<u32> = (4..12).collect();
        let top = vec![id(1, 0, 1), id(1, 1, 1), id(2, 0, 1), id(2, 1, 1)];
        TetMesh::from_parts(
            "two_cubes.msh",
            nodes,
            tets,
            vec![
                group("left", 3, 0..6, left),
                group("right", 3, 6..12, right),
                group("right_top", 2, 0..0, top),
            ],
        )
        .unwrap()
    }

    #[test]
    fn mesh_pieces_follow_volume_groups_or_the_hull() {
        let mesh = two_cubes();
        let volume = |points: &[Point3<f64>]| crate::geometry::convex_hull_volume(points).unwrap();
        let pieces = mesh_pieces(&mesh, &Pieces::Volumes).unwrap();
        assert_eq!(pieces.len(), 2);
        assert_eq!(pieces[0].0, "left");
        assert!((volume(&pieces[0].1) - 1.0).abs() < 1e-12);
        assert!((volume(&pieces[1].1) - 1.0).abs() < 1e-12);
        let hull = mesh_pieces(&mesh, &Pieces::Hull).unwrap();
        assert_eq!(hull.len(), 1);
        assert!((volume(&hull[0].1) - 2.0).abs() < 1e-12);
        let named = mesh_pieces(&mesh, &Pieces::Groups(vec!["right".into()])).unwrap();
        assert_eq!(named.len(), 1);
        assert!((volume(&named[0].1) - 1.0).abs() < 1e-12);
        let err = mesh_pieces(&mesh, &Pieces::Groups(vec!["tip".into()])).unwrap_err();
        assert!(
            err.contains("\"tip\"") && err.contains("left, right, right_top"),
            "{err}"
        );
        // A surface group is flat: it gives a degenerate hull (refused when the body
        // is built), but its nodes are there.
        let top = mesh_pieces(&mesh, &Pieces::Groups(vec!["right_top".into()])).unwrap();
        assert_eq!(top[0].1.len(), 4);
    }
}

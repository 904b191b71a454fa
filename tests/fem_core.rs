//! FEM core: patch test, rigid modes, cantilever statics and modes against beam theory,
//! eigenpairs against a dense reference, Winkler bed, error messages.
//! Meshes are structured boxes split into 6 tetra per cell (Kuhn split, conforming).

use ballast::fem::{
    DofSet, FemModel, LinearElastic, MassKind, ModeOptions, Shift, Springs, TetGeometry,
};
use nalgebra::{DMatrix, Matrix3, Point3, SymmetricEigen, Vector3};
use std::f64::consts::PI;

const LENGTH: f64 = 2.4;
const WIDTH: f64 = 0.25;
const HEIGHT: f64 = 0.22;
const TIP_LOAD: f64 = 200.0;

fn concrete() -> LinearElastic {
    LinearElastic {
        young_modulus: 45e9,
        poisson: 0.167,
        density: 2350.0,
    }
}

/// A structured box [0, size] with `cells` cells per axis, 6 tetra per cell.
struct BoxMesh {
    nodes: Vec<Point3<f64>>,
    tets: Vec<[u32; 4]>,
    cells: [usize; 3],
}

impl BoxMesh {
    fn new(size: [f64; 3], cells: [usize; 3]) -> Self {
        let (nodes, tets) =
            ballast::qdem::structured_box(nalgebra::Vector3::new(size[0], size[1], size[2]), cells);
        BoxMesh { nodes, tets, cells }
    }

    fn beam(cells: [usize; 3]) -> Self {
        Self::new([LENGTH, WIDTH, HEIGHT], cells)
    }

    fn index(&self, i: usize, j: usize, k: usize) -> u32 {
        let [nx, ny, _] = self.cells;
        (i + (nx + 1) * (j + (ny + 1) * k)) as u32
    }

    /// Nodes of the face x = 0 (end = false) or x = max (end = true).
    fn x_face(&self, end: bool) -> Vec<u32> {
        let [nx, ny, nz] = self.cells;
        let i = if end { nx } else { 0 };
        let mut face = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                face.push(self.index(i, j, k));
            }
        }
        face
    }

    /// Downward tip load `total` on the x = max face, trapezoid-weighted in y and z
    /// (a uniform traction).
    fn tip_loads(&self, total: f64) -> Vec<Vector3<f64>> {
        let [nx, ny, nz] = self.cells;
        let weight = |i: usize, n: usize| if i == 0 || i == n { 0.5 } else { 1.0 };
        let sum = (ny as f64) * (nz as f64);
        let mut loads = vec![Vector3::zeros(); self.nodes.len()];
        for k in 0..=nz {
            for j in 0..=ny {
                let w = weight(j, ny) * weight(k, nz) / sum;
                loads[self.index(nx, j, k) as usize] = Vector3::new(0.0, 0.0, -total * w);
            }
        }
        loads
    }

    /// Load-weighted mean vertical deflection of the tip face (positive down).
    fn tip_deflection(&self, displacement: &[Vector3<f64>], loads: &[Vector3<f64>]) -> f64 {
        let total: f64 = loads.iter().map(|f| f.z).sum();
        self.x_face(true)
            .iter()
            .map(|&n| -displacement[n as usize].z * loads[n as usize].z / total)
            .sum()
    }

    fn boundary_nodes(&self) -> Vec<u32> {
        let [nx, ny, nz] = self.cells;
        let mut nodes = Vec::new();
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    if i == 0 || j == 0 || k == 0 || i == nx || j == ny || k == nz {
                        nodes.push(self.index(i, j, k));
                    }
                }
            }
        }
        nodes
    }
}

fn euler_bernoulli_tip() -> f64 {
    let inertia = WIDTH * HEIGHT.powi(3) / 12.0;
    TIP_LOAD * LENGTH.powi(3) / (3.0 * concrete().young_modulus * inertia)
}

fn euler_bernoulli_first_frequency() -> f64 {
    let m = concrete();
    let inertia = WIDTH * HEIGHT.powi(3) / 12.0;
    let area = WIDTH * HEIGHT;
    1.875104f64.powi(2) / (2.0 * PI)
        * (m.young_modulus * inertia / (m.density * area * LENGTH.powi(4))).sqrt()
}

#[test]
fn patch_test_reproduces_a_linear_field_and_constant_stress() {
    let mut mesh = BoxMesh::new([1.0, 0.8, 0.6], [4, 3, 3]);
    // Move interior nodes so that the tetra are irregular.
    let boundary = mesh.boundary_nodes();
    for (n, x) in mesh.nodes.iter_mut().enumerate() {
        if boundary.binary_search(&(n as u32)).is_err() {
            let s = (n as f64 * 1.7).sin();
            *x += Vector3::new(0.04 * s, -0.03 * (n as f64).cos(), 0.02 * s * s);
        }
    }
    let gradient = Matrix3::new(1e-3, 2e-4, -3e-4, 5e-4, -7e-4, 1e-4, -2e-4, 3e-4, 4e-4);
    let offset = Vector3::new(1e-4, -2e-4, 3e-4);
    let exact = |x: &Point3<f64>| gradient * x.coords + offset;
    let mut fixed = DofSet::new();
    for &n in &boundary {
        fixed.prescribe_node(n, exact(&mesh.nodes[n as usize]));
    }
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let zero = vec![Vector3::zeros(); mesh.nodes.len()];
    let solution = model.static_solve(&fixed, &zero).unwrap();
    let scale = gradient.abs().max();
    let worst = mesh
        .nodes
        .iter()
        .zip(&solution.displacement)
        .map(|(x, u)| (u - exact(x)).norm())
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-12 * scale.max(1.0),
        "displacement error {worst:e}"
    );
    let strain = (gradient + gradient.transpose()) * 0.5;
    let stress = concrete().stress(&strain);
    for (t, s) in model.tet_stress(&solution.displacement).iter().enumerate() {
        let error = (s - stress).abs().max() / stress.abs().max();
        assert!(error < 1e-9, "tetra {t}: relative stress error {error:e}");
    }
    // The interior is free of load, so the reactions balance.
    let sum: Vector3<f64> = solution.reactions.iter().sum();
    let largest = solution
        .reactions
        .iter()
        .map(|r| r.norm())
        .fold(0.0, f64::max);
    assert!(sum.norm() < 1e-9 * largest, "reaction sum {sum}");
}

#[test]
fn rigid_motions_produce_no_force() {
    let mesh = BoxMesh::beam([6, 2, 2]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let omega = Vector3::new(0.3, -0.2, 0.5);
    let t = Vector3::new(1.0, 2.0, -1.0);
    let u: Vec<Vector3<f64>> = mesh
        .nodes
        .iter()
        .map(|x| t + omega.cross(&x.coords))
        .collect();
    let f = model.internal_forces(&u);
    let scale = model.internal_forces(&mesh.nodes.iter().map(|x| x.coords).collect::<Vec<_>>());
    let scale = scale.iter().map(|f| f.norm()).fold(0.0, f64::max);
    let worst = f.iter().map(|f| f.norm()).fold(0.0, f64::max);
    assert!(
        worst < 1e-12 * scale,
        "rigid-motion force {worst:e} (scale {scale:e})"
    );
}

#[test]
fn cantilever_tip_deflection_converges_from_below() {
    let eb = euler_bernoulli_tip();
    let reference = 92.8e-6;
    println!(
        "cantilever tip deflection, E-B {:.2} µm, reference {:.1} µm",
        eb * 1e6,
        reference * 1e6
    );
    println!(
        "{:>14} {:>8} {:>10} {:>10} {:>9}",
        "cells", "nodes", "tip µm", "error %", "time s"
    );
    let mut previous = 0.0;
    let mut last_error = f64::INFINITY;
    // Nested refinements: the compliance (tip deflection) grows monotonically.
    for cells in [[24, 1, 2], [48, 2, 4], [96, 4, 8], [192, 8, 16]] {
        let mesh = BoxMesh::beam(cells);
        let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
        let loads = mesh.tip_loads(TIP_LOAD);
        let mut system = model
            .system(&DofSet::clamped(&mesh.x_face(false)), None)
            .unwrap();
        let solution = system.static_solve(&loads).unwrap();
        let tip = mesh.tip_deflection(&solution.displacement, &loads);
        let error = (tip - reference) / reference;
        println!(
            "{:>14} {:>8} {:>10.3} {:>10.3} {:>9.3}",
            format!("{cells:?}"),
            mesh.nodes.len(),
            tip * 1e6,
            100.0 * error,
            solution.timings.total_s()
        );
        assert!(tip > previous, "deflection must grow with refinement");
        assert!(tip < 92.86e-6, "stiff linear tetra stay below Timoshenko");
        // The supports carry the load.
        let reaction: Vector3<f64> = solution.reactions.iter().sum();
        assert!(
            (reaction.z - TIP_LOAD).abs() < 1e-8 * TIP_LOAD,
            "reaction {reaction}"
        );
        if previous > 0.0 {
            // Richardson with the O(h²) rate of linear tetra in energy.
            let extrapolated = tip + (tip - previous) / 3.0;
            println!(
                "{:>14} {:>8} {:>10.3} {:>10.3}",
                "Richardson",
                "",
                extrapolated * 1e6,
                100.0 * (extrapolated - reference) / reference
            );
        }
        previous = tip;
        last_error = error;
    }
    assert!(
        last_error.abs() < 0.02,
        "finest mesh error {:.3} %",
        100.0 * last_error
    );
}

#[test]
fn cantilever_first_frequency_matches_euler_bernoulli() {
    let reference = euler_bernoulli_first_frequency();
    let mesh = BoxMesh::beam([96, 10, 9]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let modes = model
        .modes(
            &DofSet::clamped(&mesh.x_face(false)),
            4,
            None,
            &ModeOptions::default(),
        )
        .unwrap();
    println!(
        "clamped cantilever: f = {:.3?} Hz (E-B first bending {reference:.3} Hz), {} steps, {} solves, residuals {:.1e}",
        modes.frequencies_hz, modes.iterations, modes.solves, modes.residuals.iter().fold(0.0f64, |a, &b| a.max(b))
    );
    println!("timings: {}", modes.timings);
    // The first mode bends in z (the thinner direction, 0.22 m): mostly vertical tip motion.
    let tip = mesh.index(96, 5, 4) as usize;
    let shape = modes.shapes[0][tip];
    assert!(
        shape.z.abs() > 10.0 * shape.y.abs(),
        "first mode is vertical bending: {shape}"
    );
    let error = (modes.frequencies_hz[0] - reference) / reference;
    assert!(
        error.abs() < 0.03,
        "first frequency error {:.2} %",
        100.0 * error
    );
    for w in modes.frequencies_hz.windows(2) {
        assert!(w[0] <= w[1]);
    }
}

#[test]
fn free_body_has_six_rigid_modes() {
    let mesh = BoxMesh::beam([16, 3, 3]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let system = model.system(&DofSet::new(), None).unwrap();
    assert!(!system.is_anchored());
    for mass in [MassKind::Consistent, MassKind::Lumped] {
        let options = ModeOptions {
            mass,
            ..ModeOptions::default()
        };
        let modes = model.modes(&DofSet::new(), 8, None, &options).unwrap();
        let f = &modes.frequencies_hz;
        println!(
            "free body ({mass:?}): f = {f:.4?} Hz, shift {:.3e}",
            modes.shift
        );
        assert!(modes.shift < 0.0);
        for (i, fi) in f.iter().take(6).enumerate() {
            assert!(
                fi.abs() < 1e-3 * f[6],
                "rigid mode {i}: {fi} Hz vs f7 {} Hz",
                f[6]
            );
        }
        assert!(f[6] > 1.0 && f[7] >= f[6]);
    }
}

#[test]
fn lumped_mass_lowers_the_frequencies() {
    let mesh = BoxMesh::beam([24, 3, 3]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let fixed = DofSet::clamped(&mesh.x_face(false));
    let mut system = model.system(&fixed, None).unwrap();
    let consistent = system.modes(3, &ModeOptions::default()).unwrap();
    let lumped = system
        .modes(
            3,
            &ModeOptions {
                mass: MassKind::Lumped,
                ..ModeOptions::default()
            },
        )
        .unwrap();
    println!(
        "consistent {:.3?} Hz, lumped {:.3?} Hz",
        consistent.frequencies_hz, lumped.frequencies_hz
    );
    for (c, l) in consistent.frequencies_hz.iter().zip(&lumped.frequencies_hz) {
        assert!(l < c && (c - l) / c < 0.05);
    }
    // The K factor of σ = 0 is shared between both calls: only one factorisation time.
    assert!(lumped.timings.factorisation_s == 0.0);
}

/// Dense reference: K and M assembled densely from the element matrices, fixed DOFs
/// removed, L⁻¹ K L⁻ᵀ with M = L Lᵀ, nalgebra's symmetric eigen-solver.
fn dense_eigenvalues(model: &FemModel, fixed_nodes: &[u32]) -> Vec<f64> {
    let n = 3 * model.nodes().len();
    let mut k = DMatrix::<f64>::zeros(n, n);
    let mut m = DMatrix::<f64>::zeros(n, n);
    let rho = model.material().density;
    for (tet, geom) in model.tets().iter().zip(model.geometry()) {
        let ke = geom.stiffness(model.material());
        for a in 0..4 {
            for b in 0..4 {
                for i in 0..3 {
                    let r = 3 * tet[a] as usize + i;
                    for j in 0..3 {
                        let c = 3 * tet[b] as usize + j;
                        k[(r, c)] += ke[(3 * a + i, 3 * b + j)];
                    }
                    m[(r, 3 * tet[b] as usize + i)] += geom.consistent_mass(a, b, rho);
                }
            }
        }
    }
    let free: Vec<usize> = (0..n)
        .filter(|d| !fixed_nodes.contains(&((d / 3) as u32)))
        .collect();
    let k = DMatrix::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
    let m = DMatrix::from_fn(free.len(), free.len(), |i, j| m[(free[i], free[j])]);
    let l = m.cholesky().expect("M is positive definite").l();
    let l_inv = l.clone().try_inverse().unwrap();
    let a = &l_inv * k * l_inv.transpose();
    let a = (&a + a.transpose()) * 0.5;
    let mut values: Vec<f64> = SymmetricEigen::new(a).eigenvalues.iter().copied().collect();
    values.sort_by(f64::total_cmp);
    values
}

#[test]
fn modes_match_a_dense_reference() {
    let mut mesh = BoxMesh::new([1.2, 0.25, 0.22], [6, 2, 2]);
    // Irregular tetra: shift a few interior-line nodes.
    for (n, x) in mesh.nodes.iter_mut().enumerate() {
        x.x += 0.01 * ((n * 7 % 5) as f64 - 2.0);
    }
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let options = ModeOptions {
        tol: 1e-10,
        ..ModeOptions::default()
    };
    // Clamped at x = 0.
    let clamp = mesh.x_face(false);
    let reference = dense_eigenvalues(&model, &clamp);
    let modes = model
        .modes(&DofSet::clamped(&clamp), 6, None, &options)
        .unwrap();
    for (i, (l, r)) in modes.eigenvalues.iter().zip(&reference).enumerate() {
        let error = (l - r).abs() / r;
        assert!(
            error < 1e-8,
            "clamped mode {i}: {l} vs dense {r} ({error:e})"
        );
    }
    // Free: six rigid modes (compared absolutely to λ7), then elastic ones.
    let reference = dense_eigenvalues(&model, &[]);
    let modes = model.modes(&DofSet::new(), 10, None, &options).unwrap();
    let scale = reference[6];
    for (i, (l, r)) in modes.eigenvalues.iter().zip(&reference).enumerate() {
        let error = (l - r).abs() / r.abs().max(scale);
        assert!(error < 1e-8, "free mode {i}: {l} vs dense {r} ({error:e})");
    }
    // Shapes are M-orthonormal: check via the projected mass of two shapes.
    let f0 = 1.0 / (modes.frequencies_hz[6] * 2.0 * PI).powi(2);
    assert!(f0.is_finite());
}

#[test]
fn modes_with_a_given_shift_and_small_blocks_agree() {
    let mesh = BoxMesh::beam([24, 3, 3]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let fixed = DofSet::clamped(&mesh.x_face(false));
    let mut system = model.system(&fixed, None).unwrap();
    let auto = system.modes(4, &ModeOptions::default()).unwrap();
    let shifted = system
        .modes(
            4,
            &ModeOptions {
                shift: Shift::Value(-1e4),
                block_size: Some(2),
                max_basis: Some(12),
                ..ModeOptions::default()
            },
        )
        .unwrap();
    for (a, b) in auto.eigenvalues.iter().zip(&shifted.eigenvalues) {
        assert!((a - b).abs() < 1e-8 * a, "{a} vs {b}");
    }
    // A shift above the lowest eigenvalue is refused with a message.
    let above = auto.eigenvalues[1];
    let error = system
        .modes(
            2,
            &ModeOptions {
                shift: Shift::Value(above),
                ..ModeOptions::default()
            },
        )
        .unwrap_err()
        .to_string();
    assert!(error.contains("not positive definite"), "{error}");
}

#[test]
fn block_on_a_winkler_bed_settles_and_bounces() {
    // A short, stiff block on a soft bed behaves as a rigid body on springs.
    let mesh = BoxMesh::new([0.6, 0.3, 0.2], [6, 3, 2]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let [nx, ny, _] = mesh.cells;
    let mut bottom = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b) = (mesh.index(i, j, 0), mesh.index(i + 1, j, 0));
            let (c, d) = (mesh.index(i + 1, j + 1, 0), mesh.index(i, j + 1, 0));
            bottom.push([a, c, b]);
            bottom.push([a, d, c]);
        }
    }
    let bed = 1e7; // N/m³
    let springs = Springs::winkler(&mesh.nodes, &bottom, bed);
    let area = 0.6 * 0.3;
    assert!((springs.total()[(2, 2)] - bed * area).abs() < 1e-6 * bed * area);
    // The bed resists normal motion only: hold the in-plane rigid motions.
    let mut fixed = DofSet::new();
    fixed.prescribe(mesh.index(0, 0, 0), 0, 0.0);
    fixed.prescribe(mesh.index(0, 0, 0), 1, 0.0);
    fixed.prescribe(mesh.index(nx, 0, 0), 1, 0.0);
    let mut system = model.system(&fixed, Some(&springs)).unwrap();
    assert!(system.is_anchored());
    let mut loads = vec![Vector3::zeros(); mesh.nodes.len()];
    let top: Vec<u32> = (0..mesh.nodes.len() as u32)
        .filter(|&n| (mesh.nodes[n as usize].z - 0.2).abs() < 1e-12)
        .collect();
    let force = 1e4;
    for &n in &top {
        loads[n as usize].z = -force / top.len() as f64;
    }
    let solution = system.static_solve(&loads).unwrap();
    let settlement = force / (bed * area);
    let mean: f64 =
        -solution.displacement.iter().map(|u| u.z).sum::<f64>() / mesh.nodes.len() as f64;
    assert!(
        (mean - settlement).abs() < 0.02 * settlement,
        "{mean} vs {settlement}"
    );

    // Free on the bed: three in-plane rigid modes at ≈ 0 Hz, then bounce and rocking.
    let modes = model
        .modes(&DofSet::new(), 6, Some(&springs), &ModeOptions::default())
        .unwrap();
    let mass = model.mass();
    let bounce = (bed * area / mass).sqrt() / (2.0 * PI);
    println!(
        "block on bed: f = {:.3?} Hz (rigid bounce {bounce:.3} Hz)",
        modes.frequencies_hz
    );
    let f = &modes.frequencies_hz;
    for fi in &f[..3] {
        assert!(fi.abs() < 1e-3 * f[3]);
    }
    let closest = f[3..]
        .iter()
        .map(|fi| (fi - bounce).abs() / bounce)
        .fold(f64::INFINITY, f64::min);
    assert!(closest < 0.01, "no mode within 1 % of the rigid bounce");
}

#[test]
fn serial_and_parallel_runs_agree_bit_for_bit() {
    let mesh = BoxMesh::beam([48, 4, 4]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let fixed = DofSet::clamped(&mesh.x_face(false));
    let loads = mesh.tip_loads(TIP_LOAD);
    let run = || {
        let mut system = model.system(&fixed, None).unwrap();
        let u = system.static_solve(&loads).unwrap().displacement;
        let f = system
            .modes(3, &ModeOptions::default())
            .unwrap()
            .eigenvalues;
        (u, f)
    };
    let serial = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(run);
    let parallel = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap()
        .install(run);
    assert!(serial.0 == parallel.0, "displacements differ");
    assert!(serial.1 == parallel.1, "eigenvalues differ");
}

#[test]
fn bad_input_is_reported() {
    let mesh = BoxMesh::new([1.0, 1.0, 1.0], [1, 1, 1]);
    let mut tets = mesh.tets.clone();
    tets[2] = [0, 1, 2, 99];
    let error = FemModel::new(&mesh.nodes, &tets, concrete())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("tetra 2") && error.contains("node 99"),
        "{error}"
    );
    let mut nodes = mesh.nodes.clone();
    nodes.push(Point3::new(5.0, 5.0, 5.0));
    let error = FemModel::new(&nodes, &mesh.tets, concrete())
        .unwrap_err()
        .to_string();
    assert!(error.contains("node 8 belongs to no tetra"), "{error}");
    let flat = [[0u32, 1, 2, 3]];
    let error = FemModel::new(&mesh.nodes, &flat, concrete())
        .unwrap_err()
        .to_string();
    assert!(error.contains("tetra 0 is degenerate"), "{error}");
    let mut soft = concrete();
    soft.young_modulus = -1.0;
    let error = FemModel::new(&mesh.nodes, &mesh.tets, soft)
        .unwrap_err()
        .to_string();
    assert!(error.contains("young_modulus"), "{error}");

    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let loads = vec![Vector3::new(0.0, 0.0, -1.0); mesh.nodes.len()];
    let error = model
        .static_solve(&DofSet::new(), &loads)
        .unwrap_err()
        .to_string();
    assert!(error.contains("rigid-body"), "{error}");
    let error = model
        .static_solve(&DofSet::clamped(&[0, 1, 2]), &loads[..3])
        .unwrap_err()
        .to_string();
    assert!(error.contains("3 nodal loads given for 8 nodes"), "{error}");
    let error = model
        .static_solve(&DofSet::clamped(&[42]), &loads)
        .unwrap_err()
        .to_string();
    assert!(error.contains("node 42"), "{error}");
    let error = model
        .modes(
            &DofSet::clamped(&[0, 1, 2, 3]),
            100,
            None,
            &ModeOptions::default(),
        )
        .unwrap_err()
        .to_string();
    assert!(error.contains("100 modes"), "{error}");
    let _ = TetGeometry::new([Point3::origin(); 4]).is_none();
}

/// Paper resolution (≈ 96 000 nodes, 518 400 tetra): static + 4 modes, timed once.
/// `cargo test --release --test fem_core -- --ignored --nocapture`
#[test]
#[ignore]
fn paper_resolution_timing() {
    let total = std::time::Instant::now();
    let mesh = BoxMesh::beam([240, 20, 18]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let setup = total.elapsed().as_secs_f64();
    let fixed = DofSet::clamped(&mesh.x_face(false));
    let mut system = model.system(&fixed, None).unwrap();
    println!(
        "{} nodes, {} tetra, {} free DOFs, {} matrix entries, {} factor entries",
        mesh.nodes.len(),
        mesh.tets.len(),
        system.free_dof_count(),
        system.matrix_nnz(),
        system.factor_nnz()
    );
    let loads = mesh.tip_loads(TIP_LOAD);
    let solution = system.static_solve(&loads).unwrap();
    let modes = system.modes(4, &ModeOptions::default()).unwrap();
    println!(
        "tip deflection {:.3} µm; f = {:.3?} Hz ({} steps, {} solves)",
        mesh.tip_deflection(&solution.displacement, &loads) * 1e6,
        modes.frequencies_hz,
        modes.iterations,
        modes.solves
    );
    println!("model setup {setup:.3} s");
    println!("static: {}", solution.timings);
    println!("modes:  {}", modes.timings);
    println!(
        "wall time static + 4 modes: {:.3} s",
        total.elapsed().as_secs_f64()
    );
}

/// Fill of the Cholesky factor at paper resolution (symbolic only).
#[test]
#[ignore]
fn paper_resolution_fill() {
    let mesh = BoxMesh::beam([240, 20, 18]);
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let system = model
        .system(&DofSet::clamped(&mesh.x_face(false)), None)
        .unwrap();
    println!(
        "{} free DOFs, {} factor entries, {}",
        system.free_dof_count(),
        system.factor_nnz(),
        system.setup_times()
    );
}

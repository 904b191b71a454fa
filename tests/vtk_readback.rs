//! Writes one file of each kind with `ballast::output` and reads it back with VTK's own
//! readers (the `vtk` Python wheel in the project's venv, the library ParaView uses),
//! comparing names, sizes and values bit for bit.

mod common;

use common::read_with_vtk;
use std::path::{Path, PathBuf};

use ballast::output::{write_vtu, CellKind, Field, FieldValues, Grid, PvdWriter};
use serde_json::Value;

fn key(path: &Path) -> String {
    path.to_str().unwrap().to_string()
}

fn as_u64s(value: &Value) -> Vec<u64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("expected an array, got {value}"))
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect()
}

fn as_i64s(value: &Value) -> Vec<i64> {
    value
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap())
        .collect()
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// Checks everything VTK read from a `.vtu` against the grid that was written.
fn check_grid(read: &Value, grid: &Grid, what: &str) {
    assert_eq!(read["kind"], "vtu", "{what}");
    assert_eq!(read["n_points"], grid.point_count(), "{what}: points");
    assert_eq!(read["n_cells"], grid.cell_count(), "{what}: cells");
    if grid.point_count() > 0 {
        assert_eq!(read["points_type"], "double", "{what}: points stay f64");
    }
    let coordinates: Vec<f64> = grid.point_coordinates().iter().flatten().copied().collect();
    assert_eq!(
        as_u64s(&read["points"]),
        bits(&coordinates),
        "{what}: coordinates"
    );
    let types: Vec<u64> = grid
        .cell_kinds()
        .iter()
        .map(|k| k.vtk_type() as u64)
        .collect();
    assert_eq!(as_u64s(&read["cell_types"]), types, "{what}: cell types");
    assert_eq!(
        as_u64s(&read["connectivity"]),
        grid.connectivity(),
        "{what}: connectivity"
    );
    // VTK's in-memory offsets start with a zero.
    let offsets: Vec<u64> = std::iter::once(0)
        .chain(grid.offsets().iter().copied())
        .collect();
    assert_eq!(as_u64s(&read["offsets"]), offsets, "{what}: offsets");
    check_fields(
        &read["point_data"],
        grid.point_fields(),
        grid.point_count(),
        what,
    );
    check_fields(
        &read["cell_data"],
        grid.cell_fields(),
        grid.cell_count(),
        what,
    );
}

fn check_fields(read: &Value, fields: &[Field], tuples: usize, what: &str) {
    let read = read.as_array().unwrap();
    let names: Vec<&str> = read.iter().map(|a| a["name"].as_str().unwrap()).collect();
    let expected: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, expected, "{what}: array names");
    for (array, field) in read.iter().zip(fields) {
        let label = format!("{what}: {}", field.name);
        assert_eq!(array["components"], field.components, "{label}: components");
        assert_eq!(array["tuples"], tuples, "{label}: tuples");
        match &field.values {
            FieldValues::F64(values) => {
                assert_eq!(array["type"], "double", "{label}: type");
                assert_eq!(as_u64s(&array["values"]), bits(values), "{label}: values");
            }
            FieldValues::I32(values) => {
                assert_eq!(array["type"], "int", "{label}: type");
                let values: Vec<i64> = values.iter().map(|&v| v as i64).collect();
                assert_eq!(as_i64s(&array["values"]), values, "{label}: values");
            }
        }
    }
}

/// Values that catch any loss of precision or special-value mangling on the way.
fn awkward(i: usize) -> f64 {
    match i % 7 {
        0 => -0.0,
        1 => 0.1 + 0.2,
        2 => f64::MIN_POSITIVE / 3.0, // subnormal
        3 => -1.0e300,
        4 => f64::MAX,
        5 => (i as f64).sin() * 1.0e-3,
        _ => std::f64::consts::PI * i as f64,
    }
}

fn two_tetra() -> Grid {
    let points = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.1 + 0.2, 1.0 / 3.0, -1.0e-9],
    ];
    let mut grid = Grid::tetra(points, &[[0, 1, 2, 3], [1, 2, 3, 4]]).unwrap();
    let displacement: Vec<[f64; 3]> = (0..5)
        .map(|i| [awkward(3 * i), awkward(3 * i + 1), awkward(3 * i + 2)])
        .collect();
    grid.add_point_field("displacement_m", 3, displacement)
        .unwrap();
    grid.add_cell_field("von_mises_Pa", 1, vec![1.5e5, awkward(2)])
        .unwrap();
    let stress: Vec<nalgebra::Matrix3<f64>> = (0..2)
        .map(|c| nalgebra::Matrix3::from_fn(|i, j| (10 * c + 3 * i + j) as f64 + awkward(i + j)))
        .collect();
    grid.add_cell_field("stress_Pa", 9, stress.as_slice())
        .unwrap();
    grid.add_cell_field("subdomain", 1, vec![0_i32, -7])
        .unwrap();
    grid
}

fn triangles() -> Grid {
    let points = vec![
        [0.0, 0.0, 0.0],
        [0.2, 0.0, 0.0],
        [0.0, 0.2, 0.0],
        [0.0, 0.0, 0.2],
    ];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut grid = Grid::triangles(points, &faces).unwrap();
    grid.add_point_field("height_m", 1, vec![0.0, 0.0, 0.0, 0.2])
        .unwrap();
    grid.add_cell_field("grain_id", 1, vec![4_i32; 4]).unwrap();
    grid
}

fn particles(count: usize) -> Grid {
    let points = (0..count)
        .map(|i| [i as f64 * 0.01, awkward(i), -(i as f64)])
        .collect();
    let mut grid = Grid::points(points);
    let velocity: Vec<f64> = (0..3 * count).map(awkward).collect();
    grid.add_point_field("velocity_m_per_s", 3, velocity)
        .unwrap();
    let ids: Vec<i32> = (0..count as i32).map(|i| i * 3 - 100).collect();
    grid.add_cell_field("particle_id", 1, ids).unwrap();
    grid
}

fn force_chain() -> Grid {
    let points = vec![
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.05],
        [0.04, 0.0, 0.05],
        [0.04, 0.03, 0.0],
    ];
    let mut grid = Grid::lines(points, &[[0, 1], [1, 2], [2, 3]]).unwrap();
    grid.add_cell_field(
        "contact_force_N",
        3,
        vec![
            [0.0, 0.0, 12.5],
            [1.0, -2.0, 3.0],
            [awkward(3), awkward(4), awkward(5)],
        ],
    )
    .unwrap();
    grid.add_cell_field("normal_force_N", 1, vec![12.5, 3.5, 0.0])
        .unwrap();
    grid
}

#[test]
fn every_kind_reads_back_in_vtk() {
    let dir = tempfile::tempdir().unwrap();
    let mut cases: Vec<(PathBuf, Grid)> = vec![
        (dir.path().join("tetra.vtu"), two_tetra()),
        (dir.path().join("triangles.vtu"), triangles()),
        (dir.path().join("points.vtu"), particles(10)),
        (dir.path().join("lines.vtu"), force_chain()),
        // Arrays spread over several zlib blocks.
        (dir.path().join("points_5000.vtu"), particles(5000)),
        // 4096 points: arrays of exactly 1 and 3 compression blocks (vtkio's edge case).
        (dir.path().join("points_4096.vtu"), particles(4096)),
        // No contacts at all: an empty grid with its (empty) fields.
        (dir.path().join("no_contacts.vtu"), {
            let mut grid = Grid::lines(Vec::new(), &[]).unwrap();
            grid.add_cell_field("normal_force_N", 1, Vec::<f64>::new())
                .unwrap();
            grid
        }),
    ];
    // A blown-up run's last frame: NaN and infinities must survive too.
    let mut blow_up = particles(3);
    blow_up
        .add_point_field(
            "kinetic_energy_J",
            1,
            vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY],
        )
        .unwrap();
    cases.push((dir.path().join("blow_up.vtu"), blow_up));
    // A grid of mixed cells (a tetra and its surface).
    let mut mixed = Grid::tetra(triangles().point_coordinates().to_vec(), &[[0, 1, 2, 3]]).unwrap();
    mixed
        .add_cells(CellKind::Triangle, &[[0, 2, 1], [1, 2, 3]])
        .unwrap();
    mixed.add_cells(CellKind::Line, &[[0, 3]]).unwrap();
    mixed.add_cells(CellKind::Vertex, &[[3]]).unwrap();
    mixed
        .add_cell_field("kind_id", 1, vec![10_i32, 5, 5, 3, 1])
        .unwrap();
    cases.push((dir.path().join("mixed.vtu"), mixed));

    for (path, grid) in &cases {
        write_vtu(path, grid).unwrap();
    }
    let files: Vec<PathBuf> = cases.iter().map(|(path, _)| path.clone()).collect();
    let read = read_with_vtk(&files);
    for (path, grid) in &cases {
        check_grid(&read[key(path)], grid, &path.display().to_string());
    }

    // Spot checks against literal expectations, not only against the written grid.
    let tetra = &read[key(&cases[0].0)];
    assert_eq!(tetra["n_points"], 5);
    assert_eq!(tetra["n_cells"], 2);
    assert_eq!(as_u64s(&tetra["cell_types"]), [10, 10]);
    assert_eq!(tetra["point_data"][0]["name"], "displacement_m");
    assert_eq!(tetra["point_data"][0]["components"], 3);
    assert_eq!(tetra["active_vectors"], "displacement_m");
    assert_eq!(tetra["active_tensors"], "stress_Pa");
    let stress = &tetra["cell_data"][1];
    assert_eq!(stress["name"], "stress_Pa");
    assert_eq!(stress["components"], 9);
    // Row-major: t01 of cell 1 is 10 + 1 + awkward(1).
    assert_eq!(
        stress["values"][9 + 1].as_u64().unwrap(),
        (11.0 + awkward(1)).to_bits()
    );
    assert_eq!(as_i64s(&tetra["cell_data"][2]["values"]), [0, -7]);
    let lines = &read[key(&cases[3].0)];
    assert_eq!(as_u64s(&lines["cell_types"]), [3, 3, 3]);
    assert_eq!(
        lines["cell_data"][0]["values"][2].as_u64().unwrap(),
        12.5_f64.to_bits()
    );
    assert_eq!(as_u64s(&read[key(&cases[2].0)]["cell_types"]), [1; 10]);
    assert_eq!(as_u64s(&read[key(&cases[1].0)]["cell_types"]), [5; 4]);
    assert_eq!(read[key(&cases[5].0)]["n_points"], 4096);
}

#[test]
fn collection_lists_frames_with_their_times() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("impact.pvd");
    let times = [0.0, 1.0e-4, 0.1 + 0.2];
    let mut pvd = PvdWriter::create(&path).unwrap();
    let mut grids = Vec::new();
    for (step, &time) in times.iter().enumerate() {
        let mut grid = two_tetra();
        let shift: Vec<f64> = (0..15).map(|i| time * i as f64 + step as f64).collect();
        grid.add_point_field("velocity_m_per_s", 3, shift).unwrap();
        pvd.write_frame(time, format!("frames/step_{:06}.vtu", step * 10), &grid)
            .unwrap();
        grids.push(grid);
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir.path().join("frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|name| name.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");

    let read = read_with_vtk(std::slice::from_ref(&path));
    let collection = &read[key(&path)];
    assert_eq!(collection["kind"], "pvd");
    let frames = collection["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 3);
    for (step, ((frame, grid), time)) in frames.iter().zip(&grids).zip(times).enumerate() {
        assert_eq!(frame["file"], format!("frames/step_{:06}.vtu", step * 10));
        assert_eq!(
            frame["time_bits"].as_u64().unwrap(),
            time.to_bits(),
            "frame {step} time"
        );
        check_grid(&frame["frame"], grid, &format!("frame {step}"));
    }

    // Resuming at the second frame keeps two entries, and VTK sees exactly those.
    let resumed = PvdWriter::open_existing(&path, 1.0e-4).unwrap();
    assert_eq!(resumed.entries().len(), 2);
    let read = read_with_vtk(std::slice::from_ref(&path));
    assert_eq!(read[key(&path)]["frames"].as_array().unwrap().len(), 2);
}

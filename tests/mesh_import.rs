//! Mesh import: gmsh MSH 4.1 fixtures (made by gmsh from `tests/fixtures/*.geo`) read
//! into checked tetrahedral meshes, and every bad-file case failing with one clear line.

use ballast::mesh::{read_msh, tet_faces_outward, TetMesh};
use ballast::Error;
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The header line of the tetra block in `cube_tet4_100.msh` (volume 1, type 4, 100).
const VOLUME_BLOCK: &str = "3 1 4 100";

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn cube() -> TetMesh {
    read_msh(&fixture("cube_tet4_100.msh")).expect("the ASCII cube fixture reads")
}

/// Writes `text` as `name` into a fresh temporary directory (kept alive by the guard).
fn temp_file(name: &str, bytes: &[u8]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

/// Reads `path`, expects an error, and checks it is one line naming the file.
fn error_line(path: &Path) -> String {
    let error = read_msh(path).expect_err("the bad file must be refused");
    let line = error.to_string();
    println!("{line}");
    assert!(!line.contains('\n'), "error is not one line: {line}");
    let file_name = path.file_name().unwrap().to_str().unwrap();
    assert!(
        line.contains(file_name),
        "error does not name the file: {line}"
    );
    line
}

fn ascii_cube_text() -> String {
    std::fs::read_to_string(fixture("cube_tet4_100.msh")).unwrap()
}

/// Line index range (exclusive of the markers) of section `name` in an ASCII MSH text.
fn section(lines: &[String], name: &str) -> (usize, usize) {
    let start = lines.iter().position(|l| l == &format!("${name}")).unwrap();
    let end = lines
        .iter()
        .position(|l| l == &format!("$End{name}"))
        .unwrap();
    (start + 1, end)
}

#[test]
fn ascii_cube_counts_volume_and_quality() {
    let mesh = cube();
    assert_eq!(mesh.nodes.len(), 45);
    assert_eq!(mesh.tets.len(), 100);
    assert!((mesh.total_volume() - 1.0).abs() < 1e-12);
    for t in 0..mesh.tets.len() {
        assert!(mesh.tet_volume(t) > 0.0);
    }
    let quality = mesh.quality();
    assert_eq!((quality.nodes, quality.tets), (45, 100));
    assert!((quality.volume_m3 - 1.0).abs() < 1e-12);
    assert!(quality.min_quality > 0.1 && quality.min_quality <= quality.mean_quality);
    assert!(quality.mean_quality <= 1.0);
    // Element size 0.5: the smallest altitude is a fraction of it, never more.
    assert!(quality.min_altitude_m > 0.05 && quality.min_altitude_m < 0.5);
    assert!(!quality.to_string().contains('\n'));
}

#[test]
fn binary_and_ascii_fixtures_read_to_the_same_mesh() {
    let ascii = cube();
    let binary = read_msh(&fixture("cube_tet4_100_bin.msh")).unwrap();
    // gmsh prints 16 significant digits in ASCII: coordinates agree to the last bit or so.
    assert_eq!(binary.nodes.len(), ascii.nodes.len());
    for (b, a) in binary.nodes.iter().zip(&ascii.nodes) {
        assert!((b - a).norm() < 1e-15, "{b} vs {a}");
    }
    assert_eq!(binary.tets, ascii.tets);
    assert_eq!(binary.groups, ascii.groups);
    assert_eq!(binary.boundary, ascii.boundary);
}

#[test]
fn boundary_is_closed_outward_and_has_area_six() {
    let mesh = cube();
    let centre = Point3::new(0.5, 0.5, 0.5);
    let mut area = 0.0;
    let mut edge_uses: HashMap<(u32, u32), i32> = HashMap::new();
    for face in &mesh.boundary {
        let [a, b, c] = face.map(|n| mesh.nodes[n as usize]);
        let normal = (b - a).cross(&(c - a));
        area += 0.5 * normal.norm();
        // Every boundary triangle lies on a cube face and its normal points away from
        // the centre (for a convex body, outward = away from an interior point).
        let face_centre = Point3::from((a.coords + b.coords + c.coords) / 3.0);
        assert!(
            normal.dot(&(face_centre - centre)) > 0.0,
            "inward face {face:?}"
        );
        let unit = normal.normalize();
        assert!(
            [Vector3::x(), Vector3::y(), Vector3::z()]
                .iter()
                .any(|axis| (unit.dot(axis).abs() - 1.0).abs() < 1e-12),
            "face {face:?} is not on a cube side"
        );
        // Closed and consistently oriented: each directed edge is matched by its reverse.
        for (p, q) in [(face[0], face[1]), (face[1], face[2]), (face[2], face[0])] {
            *edge_uses.entry((p.min(q), p.max(q))).or_default() += if p < q { 1 } else { -1 };
        }
    }
    assert!((area - 6.0).abs() < 1e-12);
    assert!(edge_uses.values().all(|&v| v == 0));
    // Boundary faces are faces of some tetra, in their outward orientation.
    let all_faces: Vec<[u32; 3]> = mesh
        .tets
        .iter()
        .flat_map(|&t| tet_faces_outward(t))
        .collect();
    assert!(mesh.boundary.iter().all(|f| all_faces.contains(f)));
}

#[test]
fn physical_groups_carry_names_and_node_sets() {
    let mesh = cube();
    let names: Vec<&str> = mesh.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(names, ["corner", "left", "right", "cube"]);

    let left = mesh.group("left").unwrap();
    assert_eq!((left.dim, left.tag), (2, 1));
    assert!(!left.triangles.is_empty() && left.tets.is_empty());
    let on_plane = |x: f64| -> Vec<u32> {
        (0..mesh.nodes.len() as u32)
            .filter(|&n| (mesh.nodes[n as usize].x - x).abs() < 1e-12)
            .collect()
    };
    assert_eq!(left.nodes, on_plane(0.0));
    assert_eq!(mesh.group("right").unwrap().nodes, on_plane(1.0));
    let left_area: f64 = left
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|n| mesh.nodes[n as usize]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .sum();
    assert!((left_area - 1.0).abs() < 1e-12);

    let corner = mesh.group("corner").unwrap();
    assert_eq!(corner.dim, 0);
    assert_eq!(corner.nodes.len(), 1);
    assert_eq!(
        mesh.nodes[corner.nodes[0] as usize],
        Point3::new(1.0, 1.0, 1.0)
    );
    assert_eq!(
        mesh.node_nearest(Point3::new(0.9, 1.1, 1.05)),
        corner.nodes[0]
    );

    let volume = mesh.group("cube").unwrap();
    assert_eq!(volume.dim, 3);
    assert_eq!(volume.tets, (0..100).collect::<Vec<u32>>());
    assert_eq!(volume.nodes, (0..45).collect::<Vec<u32>>());

    assert!(mesh.group("tip").is_none());
    mesh.require_groups(&["left", "right", "cube"]).unwrap();
}

#[test]
fn missing_group_is_named_with_the_groups_present() {
    let mesh = cube();
    let line = mesh
        .require_groups(&["left", "tip"])
        .unwrap_err()
        .to_string();
    assert!(line.contains("cube_tet4_100.msh"), "{line}");
    assert!(
        line.ends_with(
            "physical group \"tip\" is missing (the mesh has: corner, left, right, cube)"
        ),
        "{line}"
    );
    let line = mesh
        .require_groups(&["tip", "base"])
        .unwrap_err()
        .to_string();
    assert!(line.contains("\"tip\", \"base\" are missing"), "{line}");
}

#[test]
fn inverted_tetra_is_refused_with_its_tag_and_volume() {
    // Swap two nodes of the first tetra (element 30, the first of the volume block).
    let mut lines: Vec<String> = ascii_cube_text().lines().map(String::from).collect();
    let (start, end) = section(&lines, "Elements");
    let block = (start + 1..end)
        .find(|&i| lines[i] == VOLUME_BLOCK)
        .unwrap();
    let mut fields: Vec<String> = lines[block + 1]
        .split_whitespace()
        .map(String::from)
        .collect();
    let tag = fields[0].clone();
    fields.swap(1, 2);
    lines[block + 1] = fields.join(" ");
    let (_dir, path) = temp_file("cube_tet_inverted.msh", lines.join("\n").as_bytes());
    let line = error_line(&path);
    assert!(
        line.contains(&format!("element {tag} is inverted")),
        "{line}"
    );
    assert!(line.contains("signed volume -"), "{line}");
}

#[test]
fn zero_volume_tetra_is_refused() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n\
                0 0 0\n1 0 0\n0 1 0\n1 1 0\n$EndNodes\n$Elements\n1 1 7 7\n3 1 4 1\n7 1 2 3 4\n\
                $EndElements\n";
    let (_dir, path) = temp_file("flat_tet4_1.msh", text.as_bytes());
    let line = error_line(&path);
    assert!(line.contains("element 7 has zero volume"), "{line}");
}

#[test]
fn dangling_node_is_refused_with_its_tag() {
    // Add node 46 at the cube centre, in a block of its own, used by no element.
    let text = ascii_cube_text();
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let (start, end) = section(&lines, "Nodes");
    let header: Vec<u64> = lines[start]
        .split_whitespace()
        .map(|f| f.parse().unwrap())
        .collect();
    assert_eq!(header, [27, 45, 1, 45]);
    let mut edited = lines[..start].to_vec();
    edited.push("28 46 1 46".into());
    edited.extend_from_slice(&lines[start + 1..end]);
    edited.extend(["3 1 0 1", "46", "0.5 0.5 0.5"].map(String::from));
    edited.extend_from_slice(&lines[end..]);
    let (_dir, path) = temp_file("cube_tet4_dangling.msh", edited.join("\n").as_bytes());
    let line = error_line(&path);
    assert!(line.contains("node 46 is used by no tetrahedron"), "{line}");
}

#[test]
fn hexahedral_mesh_is_refused() {
    let line = error_line(&fixture("cube_hex8_8.msh"));
    assert!(
        line.ends_with("element 1 is a 8-node hexahedron, only 4-node tetrahedra are supported"),
        "{line}"
    );
}

#[test]
fn second_order_tetra_is_refused() {
    let line = error_line(&fixture("tetra_tet10_1.msh"));
    assert!(
        line.contains("element 1 is a 10-node tetrahedron (higher order), only 4-node tetrahedra are supported"),
        "{line}"
    );
}

#[test]
fn mesh_without_tetra_is_refused() {
    // The cube's surface triangles and point only (its volume block removed).
    let lines: Vec<String> = ascii_cube_text().lines().map(String::from).collect();
    let (start, end) = section(&lines, "Elements");
    let block = (start + 1..end)
        .find(|&i| lines[i] == VOLUME_BLOCK)
        .unwrap();
    let mut header: Vec<u64> = lines[start]
        .split_whitespace()
        .map(|f| f.parse().unwrap())
        .collect();
    header[0] -= 1;
    header[1] -= 100;
    header[3] -= 100;
    let mut edited = lines[..start].to_vec();
    edited.push(
        header
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(" "),
    );
    edited.extend_from_slice(&lines[start + 1..block]);
    edited.extend_from_slice(&lines[end..]);
    let (_dir, path) = temp_file("cube_tri3_28.msh", edited.join("\n").as_bytes());
    let line = error_line(&path);
    assert!(line.contains("no 4-node tetrahedra"), "{line}");
}

#[test]
fn missing_file_is_an_io_error() {
    let path = fixture("no_such_mesh.msh");
    let error = read_msh(&path).unwrap_err();
    assert!(matches!(error, Error::Io { .. }), "{error:?}");
    assert!(error.to_string().contains("no_such_mesh.msh"));
}

#[test]
fn truncated_and_garbage_files_are_refused() {
    for fixture_name in ["cube_tet4_100.msh", "cube_tet4_100_bin.msh"] {
        let bytes = std::fs::read(fixture(fixture_name)).unwrap();
        // Cut at many places: inside the header, the names, entities, nodes, elements.
        for cut in (0..bytes.len()).step_by(97).chain([bytes.len() - 20]) {
            let (_dir, path) = temp_file(&format!("truncated_{cut}.msh"), &bytes[..cut]);
            error_line(&path);
        }
    }
    let (_dir, path) = temp_file("garbage.msh", b"\x00\x01 this is not a mesh \xff\xfe\n");
    assert!(error_line(&path).contains("not a gmsh MSH file"));
    let text = ascii_cube_text().replacen("4.1 0 8", "2.2 0 8", 1);
    let (_dir, path) = temp_file("old_format.msh", text.as_bytes());
    assert!(error_line(&path).contains("version 2.2 is not supported"));
    let text = ascii_cube_text().replacen("4.1 0 8", "4.1 1 3", 1);
    let (_dir, path) = temp_file("odd_size.msh", text.as_bytes());
    assert!(error_line(&path).contains("data size 3"));
}

#[test]
fn element_with_unknown_node_is_refused() {
    let text = ascii_cube_text();
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let (start, end) = section(&lines, "Elements");
    let block = (start + 1..end)
        .find(|&i| lines[i] == VOLUME_BLOCK)
        .unwrap();
    let mut fields: Vec<String> = lines[block + 1]
        .split_whitespace()
        .map(String::from)
        .collect();
    fields[4] = "999".into();
    let mut edited = lines.clone();
    edited[block + 1] = fields.join(" ");
    let (_dir, path) = temp_file("cube_unknown_node.msh", edited.join("\n").as_bytes());
    let line = error_line(&path);
    assert!(
        line.contains(&format!("element {} refers to node 999", fields[0])),
        "{line}"
    );
}

//! Reading gmsh MSH 4.1 files (ASCII or binary): nodes, elements and entities through
//! mshio, `$PhysicalNames` with a small parser of our own (mshio skips that section).

use super::surface::{boundary_faces, BoundaryError};
use super::{PhysicalGroup, TetMesh};
use crate::mesh::quality::tet_signed_volume;
use crate::{Error, Result};
use mshio::{ElementType, MshFile};
use nalgebra::Point3;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Tetra volumes below this fraction of the bounding-box diagonal cubed count as zero.
const ZERO_VOLUME_RELATIVE: f64 = 1e-12;

/// Reads a gmsh MSH 4.1 file (ASCII or binary) into a checked [`TetMesh`].
///
/// Node tags become 0-based indices in file order; physical groups take their names from
/// `$PhysicalNames` (`group_<tag>` when unnamed). The volume must consist of 4-node
/// tetrahedra only; surfaces may hold 3-node triangles, curves 2-node lines and points
/// 1-node points. Every failure is one line naming the file and the element, node or
/// section: a missing or unreadable file, a truncated or malformed file, another MSH
/// version, an unsupported element (second order, hexahedra, prisms, pyramids …), no
/// tetra at all, an inverted or zero-volume tetra, a node used by no tetra, overlapping
/// tetrahedra. Tetrahedra are never reoriented silently.
pub fn read_msh(path: &Path) -> Result<TetMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_msh_bytes(path, &bytes)
}

/// [`read_msh`] on the bytes of a file already in memory; `path` names it in errors.
pub fn read_msh_bytes(path: &Path, bytes: &[u8]) -> Result<TetMesh> {
    let invalid = |what: String| Error::invalid(path, what);
    check_header(bytes).map_err(invalid)?;
    let names = parse_physical_names(bytes).map_err(invalid)?;
    let msh = parse_with_mshio(bytes).map_err(invalid)?;
    build_mesh(path, &msh, &names)
}

/// Checks the `$MeshFormat` line before mshio sees it: mshio panics on some data sizes.
fn check_header(bytes: &[u8]) -> std::result::Result<(), String> {
    let head = &bytes[..bytes.len().min(256)];
    let text = String::from_utf8_lossy(head);
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    if lines.next() != Some("$MeshFormat") {
        return Err("not a gmsh MSH file (it does not start with $MeshFormat)".into());
    }
    let format = lines.next().unwrap_or("");
    let fields: Vec<&str> = format.split_whitespace().collect();
    match fields.as_slice() {
        [version, file_type, data_size] => {
            if *version != "4.1" {
                return Err(format!(
                    "MSH format version {version} is not supported (only 4.1: re-export with `gmsh -format msh41`)"
                ));
            }
            if *file_type != "0" && *file_type != "1" {
                return Err(format!(
                    "$MeshFormat file type {file_type} is neither 0 (ASCII) nor 1 (binary)"
                ));
            }
            if *data_size != "4" && *data_size != "8" {
                return Err(format!(
                    "$MeshFormat data size {data_size} is not supported (4 or 8 bytes)"
                ));
            }
            Ok(())
        }
        _ => Err(format!(
            "$MeshFormat line \"{}\" should read \"4.1 <file-type> <data-size>\"",
            format.chars().take(40).collect::<String>()
        )),
    }
}

/// Position of the first line that is exactly `marker` (ignoring trailing `\r`/spaces),
/// searched from `from`; returns the offset just after that line's end.
fn find_line(bytes: &[u8], from: usize, marker: &[u8]) -> Option<(usize, usize)> {
    let mut start = from;
    while start < bytes.len() {
        let end = bytes[start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |p| start + p);
        if bytes[start..end].trim_ascii() == marker {
            return Some((start, (end + 1).min(bytes.len())));
        }
        start = end + 1;
    }
    None
}

/// Parses `$PhysicalNames` (ASCII even in binary files) into `(dim, tag) → name`.
///
/// gmsh writes the section right after `$MeshFormat`, before any binary data, so the
/// line-wise search cannot be fooled by binary bytes that happen to spell the marker
/// unless a file puts the section after its binary sections.
fn parse_physical_names(bytes: &[u8]) -> std::result::Result<HashMap<(i32, i32), String>, String> {
    let mut names = HashMap::new();
    let Some((_, body_start)) = find_line(bytes, 0, b"$PhysicalNames") else {
        return Ok(names);
    };
    let Some((body_end, _)) = find_line(bytes, body_start, b"$EndPhysicalNames") else {
        return Err("$PhysicalNames has no $EndPhysicalNames (truncated file?)".into());
    };
    let body = std::str::from_utf8(&bytes[body_start..body_end])
        .map_err(|_| "$PhysicalNames is not valid UTF-8 text".to_string())?;
    let mut lines = body.lines().map(str::trim).filter(|l| !l.is_empty());
    let count: usize = lines
        .next()
        .and_then(|l| l.parse().ok())
        .ok_or("$PhysicalNames does not start with the number of names")?;
    let mut parsed = 0;
    for line in lines {
        let bad = || format!("$PhysicalNames entry `{line}` should read `dim tag \"name\"`");
        let mut fields = line.splitn(3, char::is_whitespace);
        let dim: i32 = fields.next().and_then(|f| f.parse().ok()).ok_or_else(bad)?;
        let tag: i32 = fields.next().and_then(|f| f.parse().ok()).ok_or_else(bad)?;
        let quoted = fields.next().map(str::trim).ok_or_else(bad)?;
        let name = quoted
            .strip_prefix('"')
            .and_then(|q| q.strip_suffix('"'))
            .ok_or_else(bad)?;
        if !(0..=3).contains(&dim) {
            return Err(format!(
                "$PhysicalNames entry `{line}` has dimension {dim} (expected 0 to 3)"
            ));
        }
        names.insert((dim, tag), name.to_string());
        parsed += 1;
    }
    if parsed != count {
        return Err(format!(
            "$PhysicalNames announces {count} names but holds {parsed}"
        ));
    }
    Ok(names)
}

/// Runs mshio and turns its multi-line backtrace into one line. mshio 0.4.2 still has
/// a few `unimplemented!`/overflow panics on malformed input: they become errors too.
fn parse_with_mshio(bytes: &[u8]) -> std::result::Result<MshFile<u64, i32, f64>, String> {
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|error| {
            // The backtrace runs from the innermost failure outwards; contexts say where.
            let backtrace = error.filtered_backtrace();
            let offset = backtrace
                .first()
                .map_or(0, |(at, _)| bytes.len() - at.len());
            let place: Vec<String> = backtrace
                .iter()
                .rev()
                .filter_map(|(_, kind)| kind.context().map(str::to_string))
                .collect();
            let reason = if offset == bytes.len() {
                "the file ends too early (truncated?)".to_string()
            } else {
                backtrace
                    .iter()
                    .find(|(_, kind)| kind.context().is_none())
                    .map_or("unexpected bytes".to_string(), |(_, kind)| {
                        kind.to_string().trim_end_matches('.').to_lowercase()
                    })
            };
            if place.is_empty() {
                format!("malformed MSH data at byte {offset}: {reason}")
            } else {
                format!(
                    "malformed MSH data at byte {offset} ({}): {reason}",
                    place.join(" > ")
                )
            }
        })
    });
    match parsed {
        Ok(result) => result,
        Err(_) => Err("malformed MSH data (the MSH parser gave up on it)".into()),
    }
}

/// Human name of an element type for error messages.
fn element_kind(element_type: ElementType) -> String {
    use ElementType::*;
    let nodes = element_type.nodes().ok();
    let with_nodes = |what: &str| match nodes {
        Some(n) => format!("{n}-node {what}"),
        None => what.to_string(),
    };
    let name = format!("{element_type:?}");
    let order = match element_type {
        Lin2 | Tri3 | Qua4 | Tet4 | Hex8 | Pri6 | Pyr5 | Pnt => "",
        _ => " (higher order)",
    };
    let family = if name.starts_with("Tet") {
        "tetrahedron"
    } else if name.starts_with("Hex") {
        "hexahedron"
    } else if name.starts_with("Pri") {
        "prism"
    } else if name.starts_with("Pyr") {
        "pyramid"
    } else if name.starts_with("Tri") {
        "triangle"
    } else if name.starts_with("Qua") {
        "quadrangle"
    } else if name.starts_with("Lin") {
        "line"
    } else if name.starts_with("Polyh") {
        "polyhedron"
    } else if name.starts_with("Polyg") {
        "polygon"
    } else {
        return format!("gmsh element of type {name}");
    };
    format!("{}{order}", with_nodes(family))
}

/// The topological dimension of the element types that the reader accepts.
fn accepted_dim(element_type: ElementType) -> Option<i32> {
    match element_type {
        ElementType::Pnt => Some(0),
        ElementType::Lin2 => Some(1),
        ElementType::Tri3 => Some(2),
        ElementType::Tet4 => Some(3),
        _ => None,
    }
}

/// Elements and nodes collected for one physical group while reading.
#[derive(Default)]
struct GroupBuilder {
    nodes: Vec<u32>,
    triangles: Vec<[u32; 3]>,
    tets: Vec<u32>,
}

fn build_mesh(
    path: &Path,
    msh: &MshFile<u64, i32, f64>,
    names: &HashMap<(i32, i32), String>,
) -> Result<TetMesh> {
    let invalid = |what: String| Error::invalid(path, what);

    // Nodes: file order gives the 0-based index. mshio keeps explicit tags only when the
    // tags are sparse; otherwise they run from min_node_tag in file order.
    let mut nodes = Vec::new();
    let mut node_tags: Vec<u64> = Vec::new();
    let mut index_of_tag: HashMap<u64, u32> = HashMap::new();
    if let Some(section) = &msh.data.nodes {
        let mut next_tag = section.min_node_tag;
        for block in &section.node_blocks {
            let mut block_tags = vec![0u64; block.nodes.len()];
            match &block.node_tags {
                Some(map) => {
                    for (&tag, &i) in map {
                        if let Some(slot) = block_tags.get_mut(i) {
                            *slot = tag;
                        }
                    }
                    if map.len() != block.nodes.len() {
                        return Err(invalid(format!(
                            "a node tag appears twice in the $Nodes block of entity ({}, {})",
                            block.entity_dim, block.entity_tag
                        )));
                    }
                }
                None => {
                    for slot in &mut block_tags {
                        *slot = next_tag;
                        next_tag += 1;
                    }
                }
            }
            for (node, tag) in block.nodes.iter().zip(block_tags) {
                let index = u32::try_from(nodes.len())
                    .map_err(|_| invalid("more than 2³² nodes".into()))?;
                if index_of_tag.insert(tag, index).is_some() {
                    return Err(invalid(format!("node {tag} is defined twice")));
                }
                if !(node.x.is_finite() && node.y.is_finite() && node.z.is_finite()) {
                    return Err(invalid(format!("node {tag} has a non-finite coordinate")));
                }
                nodes.push(Point3::new(node.x, node.y, node.z));
                node_tags.push(tag);
            }
        }
    }

    // Physical tags of each geometric entity, keyed by (dim, entity tag).
    let mut entity_groups: HashMap<(i32, i32), Vec<i32>> = HashMap::new();
    if let Some(entities) = &msh.data.entities {
        for p in &entities.points {
            entity_groups.insert((0, p.tag), p.physical_tags.clone());
        }
        for c in &entities.curves {
            entity_groups.insert((1, c.tag), c.physical_tags.clone());
        }
        for s in &entities.surfaces {
            entity_groups.insert((2, s.tag), s.physical_tags.clone());
        }
        for v in &entities.volumes {
            entity_groups.insert((3, v.tag), v.physical_tags.clone());
        }
    }
    let mut groups: BTreeMap<(i32, i32), GroupBuilder> = BTreeMap::new();
    for (&(dim, _), tags) in &entity_groups {
        for &tag in tags {
            groups.entry((dim, tag.abs())).or_default();
        }
    }

    // Elements.
    let mut tets: Vec<[u32; 4]> = Vec::new();
    let mut tet_tags: Vec<u64> = Vec::new();
    let node_index = |element: u64, tag: u64| {
        index_of_tag.get(&tag).copied().ok_or_else(|| {
            invalid(format!(
                "element {element} refers to node {tag}, which is not in $Nodes"
            ))
        })
    };
    if let Some(section) = &msh.data.elements {
        for block in &section.element_blocks {
            let Some(dim) = accepted_dim(block.element_type) else {
                let tag = block.elements.first().map_or(0, |e| e.element_tag);
                let supported = if block.entity_dim == 3 {
                    "only 4-node tetrahedra are supported"
                } else {
                    "only 4-node tetrahedra (with 3-node triangles, 2-node lines and points on lower-dimensional groups) are supported"
                };
                return Err(invalid(format!(
                    "element {tag} is a {}, {supported}",
                    element_kind(block.element_type)
                )));
            };
            let entity = (block.entity_dim, block.entity_tag);
            let physical: &[i32] = entity_groups.get(&entity).map_or(&[], Vec::as_slice);
            for element in &block.elements {
                let mut indices = Vec::with_capacity(element.nodes.len());
                for &tag in &element.nodes {
                    indices.push(node_index(element.element_tag, tag)?);
                }
                let tet_index = tets.len() as u32;
                if dim == 3 {
                    tets.push([indices[0], indices[1], indices[2], indices[3]]);
                    tet_tags.push(element.element_tag);
                }
                for &physical_tag in physical {
                    let group = groups.entry((entity.0, physical_tag.abs())).or_default();
                    group.nodes.extend_from_slice(&indices);
                    match dim {
                        3 => group.tets.push(tet_index),
                        2 => group.triangles.push([indices[0], indices[1], indices[2]]),
                        _ => {}
                    }
                }
            }
        }
    }
    if msh.data.nodes.is_none() || msh.data.elements.is_none() {
        return Err(invalid(
            "the file has no $Nodes or no $Elements section (truncated?)".into(),
        ));
    }
    if tets.is_empty() {
        return Err(invalid(
            "the mesh has no 4-node tetrahedra (mesh the volume with `gmsh -3` and, if the file has physical groups, put the volume in one)".into(),
        ));
    }

    check_volumes(&nodes, &tets, |t| format!("element {}", tet_tags[t])).map_err(invalid)?;
    check_dangling(nodes.len(), &tets, |n| format!("node {}", node_tags[n])).map_err(invalid)?;
    let boundary = boundary_faces(&tets)
        .map_err(|e| describe_boundary_error(e, |t| format!("element {}", tet_tags[t])))
        .map_err(invalid)?;

    let groups = groups
        .into_iter()
        .map(|((dim, tag), mut builder)| {
            builder.nodes.sort_unstable();
            builder.nodes.dedup();
            PhysicalGroup {
                name: names
                    .get(&(dim, tag))
                    .cloned()
                    .unwrap_or_else(|| format!("group_{tag}")),
                dim: dim as u8,
                tag,
                nodes: builder.nodes,
                triangles: builder.triangles,
                tets: builder.tets,
            }
        })
        .collect();

    Ok(TetMesh {
        source: path.to_path_buf(),
        nodes,
        tets,
        groups,
        boundary,
    })
}

/// Refuses inverted (negative) and zero-volume tetrahedra; `name(t)` names tetra `t`.
pub(crate) fn check_volumes(
    nodes: &[Point3<f64>],
    tets: &[[u32; 4]],
    name: impl Fn(usize) -> String,
) -> std::result::Result<(), String> {
    let mut lower = Point3::from([f64::INFINITY; 3]);
    let mut upper = Point3::from([f64::NEG_INFINITY; 3]);
    for p in nodes {
        lower = lower.inf(p);
        upper = upper.sup(p);
    }
    let diagonal = if nodes.is_empty() {
        0.0
    } else {
        (upper - lower).norm()
    };
    let zero_volume = ZERO_VOLUME_RELATIVE * diagonal.powi(3);
    for (t, tet) in tets.iter().enumerate() {
        let corners = tet.map(|n| nodes[n as usize]);
        let volume = tet_signed_volume(corners);
        if volume.abs() < zero_volume || volume == 0.0 {
            return Err(format!(
                "{} has zero volume ({volume:.3e} m³, below {zero_volume:.1e} = 1e-12 × bounding-box diagonal³): its four nodes are coplanar",
                name(t)
            ));
        }
        if volume < 0.0 {
            return Err(format!(
                "{} is inverted (signed volume {volume:.3e} m³ < 0; gmsh writes positive tetrahedra, so the file is corrupted)",
                name(t)
            ));
        }
    }
    Ok(())
}

/// Refuses nodes that no tetra uses; `name(n)` names node `n`.
pub(crate) fn check_dangling(
    node_count: usize,
    tets: &[[u32; 4]],
    name: impl Fn(usize) -> String,
) -> std::result::Result<(), String> {
    let mut used = vec![false; node_count];
    for &n in tets.iter().flatten() {
        used[n as usize] = true;
    }
    let unused = used.iter().filter(|&&u| !u).count();
    match used.iter().position(|&u| !u) {
        None => Ok(()),
        Some(first) => Err(format!(
            "{} is used by no tetrahedron (dangling; {unused} such node{} in all)",
            name(first),
            if unused == 1 { "" } else { "s" }
        )),
    }
}

/// One-line description of a [`BoundaryError`]; `name(t)` names tetra `t`.
pub(crate) fn describe_boundary_error(
    error: BoundaryError,
    name: impl Fn(usize) -> String,
) -> String {
    match error {
        BoundaryError::FaceSharedByMore { tets, third, .. } => format!(
            "{}, {} and {} share one face (duplicated or overlapping tetrahedra)",
            name(tets[0] as usize),
            name(tets[1] as usize),
            name(third as usize)
        ),
        BoundaryError::SameSide { tets, .. } => format!(
            "{} and {} overlap (they lie on the same side of their shared face)",
            name(tets[0] as usize),
            name(tets[1] as usize)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One corner tetra with sparse node tags 10..40, an unnamed physical volume 5 and
    /// a named physical surface on its z = 0 face.
    const SPARSE_TET: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n\
        $PhysicalNames\n1\n2 7 \"bottom face\"\n$EndPhysicalNames\n\
        $Entities\n0 0 1 1\n1 0 0 0 1 1 0 1 7 0\n1 0 0 0 1 1 1 1 5 1 1\n$EndEntities\n\
        $Nodes\n1 4 10 40\n3 1 0 4\n40\n10\n20\n30\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n\
        $Elements\n2 2 1 2\n2 1 2 1\n1 10 30 20\n3 1 4 1\n2 10 20 30 40\n$EndElements\n";

    #[test]
    fn sparse_tags_unnamed_groups_and_spaces_in_names() {
        let mesh = read_msh_bytes(Path::new("sparse.msh"), SPARSE_TET.as_bytes()).unwrap();
        // File order: node 40 is index 0, node 10 index 1, …
        assert_eq!(mesh.nodes[0], Point3::new(0.0, 0.0, 1.0));
        assert_eq!(mesh.tets, vec![[1, 2, 3, 0]]);
        assert!((mesh.total_volume() - 1.0 / 6.0).abs() < 1e-15);
        assert_eq!(mesh.boundary.len(), 4);
        let bottom = mesh.group("bottom face").unwrap();
        assert_eq!((bottom.dim, bottom.tag), (2, 7));
        assert_eq!(bottom.triangles, vec![[1, 3, 2]]);
        assert_eq!(bottom.nodes, vec![1, 2, 3]);
        let volume = mesh.group("group_5").unwrap();
        assert_eq!((volume.dim, volume.tets.clone()), (3, vec![0]));
    }

    #[test]
    fn physical_names_errors_are_one_line() {
        let cases = [
            ("$PhysicalNames\n1\n2 7 \"a\"\n", "no $EndPhysicalNames"),
            (
                "$PhysicalNames\n2\n2 7 \"a\"\n$EndPhysicalNames\n",
                "announces 2",
            ),
            (
                "$PhysicalNames\n1\n2 7 a\n$EndPhysicalNames\n",
                "should read",
            ),
            (
                "$PhysicalNames\n1\n9 7 \"a\"\n$EndPhysicalNames\n",
                "dimension 9",
            ),
            ("$PhysicalNames\nx\n$EndPhysicalNames\n", "number of names"),
        ];
        for (text, expected) in cases {
            let error = parse_physical_names(text.as_bytes()).unwrap_err();
            assert!(error.contains(expected), "{error}");
            assert!(!error.contains('\n'));
        }
        assert!(parse_physical_names(b"$MeshFormat\n").unwrap().is_empty());
    }

    #[test]
    fn header_checks() {
        assert!(check_header(b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n").is_ok());
        assert!(check_header(b"$MeshFormat\r\n4.1 1 8\r\n").is_ok());
        assert!(check_header(b"$MeshFormat\n4.1\n")
            .unwrap_err()
            .contains("should read"));
        assert!(check_header(b"")
            .unwrap_err()
            .contains("not a gmsh MSH file"));
    }

    #[test]
    fn element_kinds_read_well() {
        assert_eq!(element_kind(ElementType::Hex8), "8-node hexahedron");
        assert_eq!(element_kind(ElementType::Pri6), "6-node prism");
        assert_eq!(element_kind(ElementType::Pyr5), "5-node pyramid");
        assert_eq!(
            element_kind(ElementType::Tet10),
            "10-node tetrahedron (higher order)"
        );
        assert_eq!(element_kind(ElementType::Qua4), "4-node quadrangle");
    }

    #[test]
    fn empty_node_section_does_not_panic() {
        let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n0 0 0 0\n$EndNodes\n\
                    $Elements\n0 0 0 0\n$EndElements\n";
        let error = read_msh_bytes(Path::new("empty.msh"), text.as_bytes()).unwrap_err();
        assert!(error.to_string().starts_with("empty.msh: "), "{error}");
    }
}

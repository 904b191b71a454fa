//! Boundary surface of a tetrahedral mesh: the faces owned by exactly one tetra.

use std::collections::HashMap;

/// The four faces of a positively oriented tetra `(a, b, c, d)`, each ordered so that its
/// right-hand normal points out of the tetra; face `i` is the one opposite corner `i`.
pub fn tet_faces_outward(tet: [u32; 4]) -> [[u32; 3]; 4] {
    let [a, b, c, d] = tet;
    [[b, c, d], [a, d, c], [a, b, d], [a, c, b]]
}

/// Why a set of tetrahedra has no well-defined boundary (indices into the tetra list).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoundaryError {
    /// A face is shared by more than two tetrahedra (duplicated or overlapping elements).
    FaceSharedByMore {
        /// The face (0-based node indices).
        face: [u32; 3],
        /// The first two tetrahedra that hold it.
        tets: [u32; 2],
        /// The third tetra that holds it.
        third: u32,
    },
    /// Two tetrahedra lie on the same side of their shared face (they overlap).
    SameSide {
        /// The face (0-based node indices).
        face: [u32; 3],
        /// The two tetrahedra.
        tets: [u32; 2],
    },
}

/// Sorted key of a face and the parity of the permutation that sorts it (`true` = odd).
fn face_key(face: [u32; 3]) -> ([u32; 3], bool) {
    let mut key = face;
    let mut odd = false;
    // Three-element bubble sort, counting swaps.
    for (i, j) in [(0, 1), (1, 2), (0, 1)] {
        if key[i] > key[j] {
            key.swap(i, j);
            odd = !odd;
        }
    }
    (key, odd)
}

/// Faces that belong to exactly one of the positively oriented `tets`, oriented outward,
/// in the order of their first appearance (tetra by tetra, faces as in
/// [`tet_faces_outward`]). Interior faces must be shared by two tetrahedra that see
/// the face with opposite orientations; anything else is reported as a [`BoundaryError`].
pub fn boundary_faces(tets: &[[u32; 4]]) -> Result<Vec<[u32; 3]>, BoundaryError> {
    struct Seen {
        face: [u32; 3],
        odd: bool,
        owners: [u32; 2],
        count: u8,
    }
    let mut index_of: HashMap<[u32; 3], usize> = HashMap::with_capacity(tets.len() * 2);
    let mut seen: Vec<Seen> = Vec::with_capacity(tets.len() * 2);
    for (tet_index, &tet) in tets.iter().enumerate() {
        let tet_index = tet_index as u32;
        for face in tet_faces_outward(tet) {
            let (key, odd) = face_key(face);
            match index_of.get(&key) {
                None => {
                    index_of.insert(key, seen.len());
                    seen.push(Seen {
                        face,
                        odd,
                        owners: [tet_index, u32::MAX],
                        count: 1,
                    });
                }
                Some(&at) => {
                    let entry = &mut seen[at];
                    if entry.count >= 2 {
                        return Err(BoundaryError::FaceSharedByMore {
                            face: entry.face,
                            tets: entry.owners,
                            third: tet_index,
                        });
                    }
                    if entry.odd == odd {
                        return Err(BoundaryError::SameSide {
                            face: entry.face,
                            tets: [entry.owners[0], tet_index],
                        });
                    }
                    entry.owners[1] = tet_index;
                    entry.count = 2;
                }
            }
        }
    }
    Ok(seen
        .into_iter()
        .filter(|s| s.count == 1)
        .map(|s| s.face)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_tet_has_four_boundary_faces() {
        let faces = boundary_faces(&[[0, 1, 2, 3]]).unwrap();
        assert_eq!(faces, tet_faces_outward([0, 1, 2, 3]).to_vec());
    }

    #[test]
    fn two_tets_share_one_face() {
        // Nodes 0..3: origin and unit axes; node 4 = (1, 1, 1) beyond face (1, 2, 3).
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
        let faces = boundary_faces(&tets).unwrap();
        assert_eq!(faces.len(), 6);
        assert!(!faces.iter().any(|f| face_key(*f).0 == [1, 2, 3]));
    }

    #[test]
    fn overlapping_tets_are_reported() {
        assert_eq!(
            boundary_faces(&[[0, 1, 2, 3], [0, 1, 2, 4]]),
            Err(BoundaryError::SameSide {
                face: [0, 2, 1],
                tets: [0, 1]
            })
        );
        assert_eq!(
            boundary_faces(&[[0, 1, 2, 3], [1, 2, 3, 4], [1, 2, 3, 5]]),
            Err(BoundaryError::FaceSharedByMore {
                face: [1, 2, 3],
                tets: [0, 1],
                third: 2
            })
        );
    }

    #[test]
    fn face_key_parity() {
        assert_eq!(face_key([1, 2, 3]), ([1, 2, 3], false));
        assert_eq!(face_key([2, 3, 1]), ([1, 2, 3], false));
        assert_eq!(face_key([2, 1, 3]), ([1, 2, 3], true));
        assert_eq!(face_key([3, 2, 1]), ([1, 2, 3], true));
    }
}

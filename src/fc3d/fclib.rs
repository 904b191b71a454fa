//! FCLIB HDF5 files (through `hdf5-metno`, which links the system libhdf5):
//! `/fclib_local` (W, q, µ) and `/fclib_global` (M, H, f, w, µ with a diagonal M,
//! reduced to `W = Hᵀ M⁻¹ H`, `q = Hᵀ M⁻¹ f + w`).
//!
//! A sparse matrix group holds `nzmax`, `m`, `n`, `nz` and `p`, `i`, `x`: `nz = −2` is
//! CSR (p row pointers, i column indices), `nz = −1` CSC, `nz ≥ 0` a triplet list with
//! i the rows and p the columns. `/solution` and `/guesses` are not read.

use std::collections::HashMap;
use std::path::Path;

use hdf5_metno as hdf5;

use super::Fc3dFormat;
use crate::nscd::{Block3, DelassusBlocks, FrictionProblem};

/// A sparse matrix as (row, column, value) triplets (duplicates to be summed).
#[derive(Debug, Clone, PartialEq)]
pub struct Triplets {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub columns: usize,
    /// The entries.
    pub entries: Vec<(usize, usize, f64)>,
}

/// Reads an FCLIB file in the local or the global layout.
pub fn read(path: &Path) -> crate::Result<(FrictionProblem, Fc3dFormat)> {
    let err = |what: String| crate::Error::invalid(path, what);
    let file = hdf5::File::open(path).map_err(|e| err(format!("HDF5: {e}")))?;
    if let Ok(local) = file.group("fclib_local") {
        read_local(&local).map_err(err)
    } else if let Ok(global) = file.group("fclib_global") {
        read_global(&global).map_err(err)
    } else {
        Err(err("no /fclib_local or /fclib_global group".into()))
    }
}

fn reals(group: &hdf5::Group, name: &str) -> Result<Vec<f64>, String> {
    let path = format!("{}/{name}", group.name());
    group
        .dataset(name)
        .and_then(|d| d.read_raw::<f64>())
        .map_err(|e| format!("{path}: {e}"))
}

fn integers(group: &hdf5::Group, name: &str) -> Result<Vec<i64>, String> {
    let path = format!("{}/{name}", group.name());
    group
        .dataset(name)
        .and_then(|d| d.read_raw::<i64>())
        .map_err(|e| format!("{path}: {e}"))
}

fn integer(group: &hdf5::Group, name: &str) -> Result<i64, String> {
    let path = format!("{}/{name}", group.name());
    let values = integers(group, name)?;
    match values.as_slice() {
        [value] => Ok(*value),
        _ => Err(format!(
            "{path}: expected one integer, found {}",
            values.len()
        )),
    }
}

fn index(value: i64, bound: usize, what: &str) -> Result<usize, String> {
    usize::try_from(value)
        .ok()
        .filter(|&v| v < bound)
        .ok_or_else(|| format!("{what} {value} out of range 0..{bound}"))
}

/// Reads an FCLIB sparse matrix group.
pub fn read_sparse(group: &hdf5::Group) -> Result<Triplets, String> {
    let name = group.name();
    let dimension = |key: &str| {
        integer(group, key)
            .and_then(|v| usize::try_from(v).map_err(|_| format!("{name}/{key} is negative ({v})")))
    };
    let (rows, columns) = (dimension("m")?, dimension("n")?);
    let nz = integer(group, "nz")?;
    let p = integers(group, "p")?;
    let i = integers(group, "i")?;
    let x = reals(group, "x")?;
    let mut entries = Vec::with_capacity(x.len());
    match nz {
        -2 | -1 => {
            let (outer, inner) = if nz == -2 {
                (rows, columns)
            } else {
                (columns, rows)
            };
            if p.len() < outer + 1 {
                return Err(format!(
                    "{name}/p has {} pointers, expected {}",
                    p.len(),
                    outer + 1
                ));
            }
            let end = index(p[outer], i.len().min(x.len()) + 1, &format!("{name}/p end"))?;
            for o in 0..outer {
                let (from, to) = (p[o], p[o + 1]);
                if from < 0 || to < from || to as usize > end {
                    return Err(format!("{name}/p is not a rising pointer array at {o}"));
                }
                for k in from as usize..to as usize {
                    let other = index(i[k], inner, &format!("{name}/i[{k}]"))?;
                    let (r, c) = if nz == -2 { (o, other) } else { (other, o) };
                    entries.push((r, c, x[k]));
                }
            }
        }
        count if count >= 0 => {
            let count = count as usize;
            if i.len() < count || p.len() < count || x.len() < count {
                return Err(format!("{name}: nz = {count} but i, p, x are shorter"));
            }
            for k in 0..count {
                let r = index(i[k], rows, &format!("{name}/i[{k}] (row)"))?;
                let c = index(p[k], columns, &format!("{name}/p[{k}] (column)"))?;
                entries.push((r, c, x[k]));
            }
        }
        other => return Err(format!("{name}/nz = {other} is not a known storage")),
    }
    if let Some(&(r, c, _)) = entries.iter().find(|e| !e.2.is_finite()) {
        return Err(format!("{name}: entry ({r}, {c}) is not finite"));
    }
    Ok(Triplets {
        rows,
        columns,
        entries,
    })
}

fn spacedim(group: &hdf5::Group) -> Result<(), String> {
    match integer(group, "spacedim")? {
        3 => Ok(()),
        d => Err(format!("{}/spacedim is {d}, only 3 is read", group.name())),
    }
}

fn vector(group: &hdf5::Group, name: &str, len: usize) -> Result<Vec<f64>, String> {
    let v = reals(group, name)?;
    if v.len() != len {
        return Err(format!(
            "{}/{name} has {} values, expected {len}",
            group.name(),
            v.len()
        ));
    }
    Ok(v)
}

/// Sums scalar entries into 3 × 3 blocks.
fn to_blocks(
    entries: impl IntoIterator<Item = (usize, usize, f64)>,
) -> Vec<(usize, usize, Block3)> {
    let mut blocks: HashMap<(usize, usize), Block3> = HashMap::new();
    for (r, c, v) in entries {
        blocks.entry((r / 3, c / 3)).or_insert([0.0; 9])[3 * (r % 3) + c % 3] += v;
    }
    let mut list: Vec<_> = blocks
        .into_iter()
        .map(|((a, b), block)| (a, b, block))
        .collect();
    list.sort_by_key(|&(a, b, _)| (a, b));
    list
}

fn read_local(group: &hdf5::Group) -> Result<(FrictionProblem, Fc3dFormat), String> {
    spacedim(group)?;
    let w = read_sparse(
        &group
            .group("W")
            .map_err(|e| format!("fclib_local/W: {e}"))?,
    )?;
    if w.rows != w.columns || w.rows % 3 != 0 || w.rows == 0 {
        return Err(format!(
            "fclib_local/W is {} × {}, expected 3nc × 3nc",
            w.rows, w.columns
        ));
    }
    let nc = w.rows / 3;
    let vectors = group
        .group("vectors")
        .map_err(|e| format!("fclib_local/vectors: {e}"))?;
    let q = vector(&vectors, "q", 3 * nc)?;
    let mu = vector(&vectors, "mu", nc)?;
    let delassus = DelassusBlocks::from_blocks(nc, to_blocks(w.entries));
    let problem = FrictionProblem::new(delassus, q, mu).map_err(|e| e.to_string())?;
    Ok((problem, Fc3dFormat::FclibLocal))
}

fn read_global(group: &hdf5::Group) -> Result<(FrictionProblem, Fc3dFormat), String> {
    spacedim(group)?;
    let m = read_sparse(
        &group
            .group("M")
            .map_err(|e| format!("fclib_global/M: {e}"))?,
    )?;
    let h = read_sparse(
        &group
            .group("H")
            .map_err(|e| format!("fclib_global/H: {e}"))?,
    )?;
    let n = m.rows;
    if m.columns != n || h.rows != n || h.columns % 3 != 0 || h.columns == 0 {
        return Err(format!(
            "fclib_global: M is {} × {} and H {} × {}; expected n × n and n × 3nc",
            m.rows, m.columns, h.rows, h.columns
        ));
    }
    let nc = h.columns / 3;
    let mut mass = vec![0.0; n];
    for &(r, c, v) in &m.entries {
        if r != c && v != 0.0 {
            return Err(format!(
                "fclib_global/M has an off-diagonal entry at ({r}, {c}): only a diagonal M is read"
            ));
        }
        mass[r] += v;
    }
    if let Some(k) = mass.iter().position(|&v| v <= 0.0) {
        return Err(format!(
            "fclib_global/M: diagonal entry {k} is {} (must be > 0)",
            mass[k]
        ));
    }
    let vectors = group
        .group("vectors")
        .map_err(|e| format!("fclib_global/vectors: {e}"))?;
    let f = vector(&vectors, "f", n)?;
    let w_free = vector(&vectors, "w", 3 * nc)?;
    let mu = vector(&vectors, "mu", nc)?;
    // Rows of H (one per degree of freedom), then W = Σ_k H_k·ᵀ H_k· / M_kk.
    let mut by_row: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for &(r, c, v) in &h.entries {
        if v != 0.0 {
            by_row[r].push((c, v));
        }
    }
    let mut q = w_free;
    let mut products = Vec::new();
    for (k, row) in by_row.iter().enumerate() {
        let inverse_mass = 1.0 / mass[k];
        for &(i, hi) in row {
            q[i] += hi * inverse_mass * f[k];
            for &(j, hj) in row {
                products.push((i, j, hi * hj * inverse_mass));
            }
        }
    }
    let delassus = DelassusBlocks::from_blocks(nc, to_blocks(products));
    let problem = FrictionProblem::new(delassus, q, mu).map_err(|e| e.to_string())?;
    Ok((problem, Fc3dFormat::FclibGlobal))
}

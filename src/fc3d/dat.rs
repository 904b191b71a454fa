//! The Siconos `.dat` text format: `d nc`, W (storage 0 dense or 1 block-sparse, values
//! column-major), q, µ; anything after µ is ignored.

use super::Fc3dFormat;
use crate::nscd::{Block3, DelassusBlocks, FrictionProblem};

/// Whitespace-separated tokens with their ordinal, for errors that say where.
struct Tokens<'a> {
    inner: std::str::SplitAsciiWhitespace<'a>,
    count: usize,
}

impl<'a> Tokens<'a> {
    fn next_str(&mut self, what: &str) -> Result<&'a str, String> {
        self.count += 1;
        self.inner
            .next()
            .ok_or_else(|| format!("ends before {what} (token {})", self.count))
    }

    fn int(&mut self, what: &str) -> Result<usize, String> {
        let token = self.next_str(what)?;
        token
            .parse::<i64>()
            .ok()
            .and_then(|v| usize::try_from(v).ok())
            .ok_or_else(|| {
                format!(
                    "{what}: expected a non-negative integer at token {}, found {token:?}",
                    self.count
                )
            })
    }

    fn real(&mut self, what: &str) -> Result<f64, String> {
        let token = self.next_str(what)?;
        token
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                format!(
                    "{what}: expected a finite number at token {}, found {token:?}",
                    self.count
                )
            })
    }

    fn expect(&mut self, what: &str, value: usize) -> Result<(), String> {
        let found = self.int(what)?;
        if found != value {
            return Err(format!(
                "{what} is {found}, expected {value} (token {})",
                self.count
            ));
        }
        Ok(())
    }
}

/// Parses the text of a `.dat` file; the error names the token and what was expected.
pub fn parse(text: &str) -> Result<(FrictionProblem, Fc3dFormat), String> {
    let mut t = Tokens {
        inner: text.split_ascii_whitespace(),
        count: 0,
    };
    t.expect("dimension d", 3)?;
    let nc = t.int("number of contacts nc")?;
    if nc == 0 {
        return Err("no contacts (nc = 0)".into());
    }
    let n = 3 * nc;
    let storage = t.int("matrix storage type")?;
    t.expect("matrix rows", n)?;
    t.expect("matrix columns", n)?;
    let (delassus, format) = match storage {
        0 => {
            t.expect("dense matrix rows", n)?;
            t.expect("dense matrix columns", n)?;
            let mut row_major = vec![0.0; n * n];
            for j in 0..n {
                for i in 0..n {
                    row_major[i * n + j] = t.real("W value")?;
                }
            }
            (
                DelassusBlocks::from_dense(nc, &row_major),
                Fc3dFormat::DatDense,
            )
        }
        1 => (block_sparse(&mut t, nc)?, Fc3dFormat::DatBlockSparse),
        other => {
            return Err(format!(
                "matrix storage type {other} (0 dense and 1 block-sparse are read)"
            ))
        }
    };
    let q = (0..n).map(|_| t.real("q")).collect::<Result<Vec<_>, _>>()?;
    let mu = (0..nc)
        .map(|_| t.real("µ"))
        .collect::<Result<Vec<_>, _>>()?;
    let problem = FrictionProblem::new(delassus, q, mu).map_err(|e| e.to_string())?;
    Ok((problem, format))
}

fn block_sparse(t: &mut Tokens, nc: usize) -> Result<DelassusBlocks, String> {
    let blocks = t.int("number of blocks")?;
    t.expect("block rows", nc)?;
    t.expect("block columns", nc)?;
    for what in ["cumulative row block size", "cumulative column block size"] {
        for k in 0..nc {
            t.expect(what, 3 * (k + 1))?;
        }
    }
    t.expect("row pointer count", nc + 1)?;
    t.expect("filled block count", blocks)?;
    let row_pointer = (0..=nc)
        .map(|_| t.int("block row pointer"))
        .collect::<Result<Vec<_>, _>>()?;
    if row_pointer[0] != 0
        || row_pointer[nc] != blocks
        || row_pointer.windows(2).any(|w| w[0] > w[1])
    {
        return Err(format!("block row pointers must rise from 0 to {blocks}"));
    }
    let columns = (0..blocks)
        .map(|_| t.int("block column index"))
        .collect::<Result<Vec<_>, _>>()?;
    if let Some(&c) = columns.iter().find(|&&c| c >= nc) {
        return Err(format!("block column index {c} ≥ nc = {nc}"));
    }
    let mut triplets = Vec::with_capacity(blocks);
    for row in 0..nc {
        let range = row_pointer[row]..row_pointer[row + 1];
        for (k, &column) in range.clone().zip(&columns[range]) {
            t.expect("block number", k)?;
            let mut block: Block3 = [0.0; 9];
            for j in 0..3 {
                for i in 0..3 {
                    block[3 * i + j] = t.real("block value")?;
                }
            }
            triplets.push((row, column, block));
        }
    }
    Ok(DelassusBlocks::from_blocks(nc, triplets))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_is_column_major() {
        let text = "3 1 0 3 3 3 3  1 2 3 4 5 6 7 8 9  -1 0 0  0.5";
        let (p, format) = parse(text).unwrap();
        assert_eq!(format, Fc3dFormat::DatDense);
        assert_eq!(
            *p.delassus.diagonal(0),
            [1.0, 4.0, 7.0, 2.0, 5.0, 8.0, 3.0, 6.0, 9.0]
        );
        assert_eq!(p.friction, vec![0.5]);
    }

    #[test]
    fn block_sparse_two_contacts() {
        let block = |k: usize, v: f64| format!("{k} {v} 0 0 0 {v} 0 0 0 {v}");
        let text = format!(
            "3 2 1 6 6 3 2 2 3 6 3 6 3 3 0 2 3 0 1 1 {} {} {} 1 2 3 4 5 6 0.1 0.2 trailing",
            block(0, 2.0),
            block(1, 0.5),
            block(2, 3.0)
        );
        let (p, format) = parse(&text).unwrap();
        assert_eq!(format, Fc3dFormat::DatBlockSparse);
        assert_eq!(p.delassus.diagonal(1)[4], 3.0);
        assert_eq!(p.delassus.row(0).1[0][8], 0.5);
        assert_eq!(p.free_velocity[5], 6.0);
    }

    #[test]
    fn errors_name_the_token() {
        let err = parse("3 1 0 3 3 3 3 1 2").unwrap_err();
        assert!(err.contains("ends before W value"), "{err}");
        let err = parse("2 1").unwrap_err();
        assert!(err.contains("dimension d is 2"), "{err}");
        let err = parse("3 1 0 3 3 3 3 1 2 x").unwrap_err();
        assert!(err.contains("\"x\""), "{err}");
    }
}

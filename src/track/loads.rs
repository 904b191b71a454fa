//! Rail-seat loads from a CSV `time_s,Rp1,Rp2` (N, compressive positive): measured
//! (seed 004 Figure 5) or written by `ballast-post train-load`. Linearly interpolated
//! between rows by the QDEM load table (seed 004 §4: 10 kHz data, 10 MHz steps).

use std::path::Path;

use crate::{Error, Result};

/// The load series.
#[derive(Debug, Clone, PartialEq)]
pub struct RailSeatLoads {
    /// Times (s), strictly increasing.
    pub times: Vec<f64>,
    /// Load on rail seat 1 (N).
    pub rp1: Vec<f64>,
    /// Load on rail seat 2 (N).
    pub rp2: Vec<f64>,
}

impl RailSeatLoads {
    /// Reads `path`; errors name the file, the line and what is wrong.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse(path, &text)
    }

    /// Parses CSV text (header `time_s,Rp1,Rp2`, in any column order; other columns ignored).
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let bad = |what: String| Error::invalid(path, what);
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines
            .next()
            .ok_or_else(|| bad("empty file (expected a header time_s,Rp1,Rp2)".into()))?;
        let cols: Vec<&str> = header.split(',').map(str::trim).collect();
        let find = |name: &str| {
            cols.iter()
                .position(|c| *c == name)
                .ok_or_else(|| bad(format!("line 1: no column {name} (header: {header})")))
        };
        let (ct, c1, c2) = (find("time_s")?, find("Rp1")?, find("Rp2")?);
        let mut out = RailSeatLoads {
            times: Vec::new(),
            rp1: Vec::new(),
            rp2: Vec::new(),
        };
        for (i, line) in lines {
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let get = |c: usize, name: &str| -> Result<f64> {
                let f = fields
                    .get(c)
                    .ok_or_else(|| bad(format!("line {}: no value for {name}", i + 1)))?;
                let v: f64 = f.parse().map_err(|_| {
                    bad(format!("line {}: {name} = \"{f}\" is not a number", i + 1))
                })?;
                if v.is_finite() {
                    Ok(v)
                } else {
                    Err(bad(format!("line {}: {name} is not finite", i + 1)))
                }
            };
            let t = get(ct, "time_s")?;
            if out.times.last().is_some_and(|&last| t <= last) {
                return Err(bad(format!(
                    "line {}: time_s = {t} does not increase",
                    i + 1
                )));
            }
            out.times.push(t);
            out.rp1.push(get(c1, "Rp1")?);
            out.rp2.push(get(c2, "Rp2")?);
        }
        if out.times.len() < 2 {
            return Err(bad("fewer than two rows of loads".into()));
        }
        Ok(out)
    }

    /// Linear interpolation of (Rp1, Rp2) at `t` (constant beyond the ends).
    pub fn at(&self, t: f64) -> (f64, f64) {
        let k = self.times.partition_point(|&x| x <= t);
        if k == 0 {
            return (self.rp1[0], self.rp2[0]);
        }
        if k == self.times.len() {
            return (self.rp1[k - 1], self.rp2[k - 1]);
        }
        let w = (t - self.times[k - 1]) / (self.times[k] - self.times[k - 1]);
        let lerp = |v: &[f64]| v[k - 1] + w * (v[k] - v[k - 1]);
        (lerp(&self.rp1), lerp(&self.rp2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_interpolates_and_names_bad_rows() {
        let p = Path::new("loads.csv");
        let l = RailSeatLoads::parse(p, "time_s,Rp1,Rp2\n0,0,10\n0.1,100,20\n").unwrap();
        assert_eq!(l.at(0.05), (50.0, 15.0));
        assert_eq!(l.at(1.0), (100.0, 20.0));
        let e = RailSeatLoads::parse(p, "time_s,Rp1\n0,0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("loads.csv") && e.contains("no column Rp2"),
            "{e}"
        );
        let e = RailSeatLoads::parse(p, "time_s,Rp1,Rp2\n0,0,0\n0,1,x\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3"), "{e}");
    }
}

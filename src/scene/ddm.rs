//! The `[ddm]` table of NSCD scenes (`[deposit.ddm]` in ballast-pack scenes): domain
//! decomposition of the contact solve ([`crate::ddm`]).
//!
//! ```toml
//! [ddm]
//! driver = "synchronous"   # or "asynchronous", or "none" (plain sequential NLGS)
//! slabs = 3                # equal slabs along x over the grains' extent, or
//! # cuts = ["0.6 m", "1.2 m"]  # slabs along x cut at these x, or
//! # grid = [2, 2]          # an nx × ny grid over the grains' plan extent, or
//! # balanced = 6           # slabs along x with equal contact counts at the start
//! sweeps = [1, 1]          # NLGS sweeps per DDM iteration: subdomains (n), interface (m)
//! ```
//!
//! With none of `slabs`, `cuts` or `grid`, the caller's default partition applies (one
//! slab per sleeper in ballast-pack). The partition is part of the scene, never taken
//! from the thread count, so a run gives the same result on any number of threads.

use serde::Deserialize;

use super::{Length, Validate, Validator};
use crate::ddm::{DdmOptions, Driver, Partitioning};
use crate::nscd::DdmSetup;

/// `[ddm]`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DdmSpec {
    /// "synchronous", "asynchronous" or "none".
    #[serde(default = "synchronous")]
    pub driver: String,
    /// Equal slabs along x.
    #[serde(default)]
    pub slabs: Option<usize>,
    /// Slab cuts along x.
    #[serde(default)]
    pub cuts: Option<Vec<Length>>,
    /// An nx × ny grid in plan.
    #[serde(default)]
    pub grid: Option<[usize; 2]>,
    /// Slabs along x with equal contact counts at the start (more than threads).
    #[serde(default)]
    pub balanced: Option<usize>,
    /// NLGS sweeps per DDM iteration in the subdomains and on the interface.
    #[serde(default = "one_one")]
    pub sweeps: [usize; 2],
}

fn synchronous() -> String {
    "synchronous".to_string()
}

fn one_one() -> [usize; 2] {
    [1, 1]
}

impl Default for DdmSpec {
    fn default() -> Self {
        DdmSpec {
            driver: synchronous(),
            slabs: None,
            cuts: None,
            grid: None,
            balanced: None,
            sweeps: one_one(),
        }
    }
}

impl Validate for DdmSpec {
    fn validate(&self, v: &mut Validator) {
        v.check(
            "driver",
            matches!(
                self.driver.as_str(),
                "synchronous" | "asynchronous" | "none"
            ),
            format!(
                "\"{}\" is not a driver: use \"synchronous\", \"asynchronous\" or \"none\"",
                self.driver
            ),
        );
        let given = [
            self.slabs.is_some(),
            self.cuts.is_some(),
            self.grid.is_some(),
            self.balanced.is_some(),
        ];
        v.check(
            "",
            given.iter().filter(|&&g| g).count() <= 1,
            "give at most one of slabs, cuts, grid or balanced",
        );
        if let Some(n) = self.balanced {
            v.check("balanced", n >= 1, "must be at least 1");
        }
        if let Some(n) = self.slabs {
            v.check("slabs", n >= 1, "must be at least 1");
        }
        if let Some(cuts) = &self.cuts {
            v.check(
                "cuts",
                cuts.windows(2).all(|w| w[0].si() < w[1].si()),
                "must increase",
            );
        }
        if let Some([nx, ny]) = self.grid {
            v.check("grid", nx >= 1 && ny >= 1, "needs at least 1 box each way");
        }
        v.check(
            "sweeps",
            self.sweeps[0] >= 1 && self.sweeps[1] >= 1,
            "needs at least one sweep in the subdomains and on the interface",
        );
    }
}

impl DdmSpec {
    /// The DDM of the solve, or `None` for driver "none". `extent` is the grains' plan
    /// box `[x_min, x_max, y_min, y_max]` (for `slabs` and `grid`); `contacts_x` the
    /// x of the contacts at the start (for `balanced`; without any, `balanced` gives
    /// even slabs); `default` the partition when the table names none.
    pub fn setup(
        &self,
        extent: [f64; 4],
        contacts_x: &[f64],
        default: Partitioning,
    ) -> Option<DdmSetup> {
        let driver = match self.driver.as_str() {
            "asynchronous" => Driver::Asynchronous,
            "none" => return None,
            _ => Driver::Synchronous,
        };
        let partitioning = if let Some(n) = self.slabs {
            Partitioning::even_slabs(0, extent[0], extent[1], n)
        } else if let Some(cuts) = &self.cuts {
            Partitioning::Slabs {
                axis: 0,
                cuts: cuts.iter().map(|c| c.si()).collect(),
            }
        } else if let Some(n) = self.balanced {
            if contacts_x.is_empty() {
                Partitioning::even_slabs(0, extent[0], extent[1], n)
            } else {
                Partitioning::balanced_slabs(0, contacts_x, n)
            }
        } else if let Some([nx, ny]) = self.grid {
            Partitioning::Grid {
                nx,
                ny,
                min: [extent[0], extent[2]],
                max: [extent[1], extent[3]],
            }
        } else {
            default
        };
        Some(DdmSetup {
            partitioning,
            options: DdmOptions {
                driver,
                subdomain_sweeps: self.sweeps[0],
                interface_sweeps: self.sweeps[1],
            },
        })
    }
}

//! An edge that slides over a corner of another stone (issue #6's deep pairs): two
//! stones of the impact bed, the second dropped at 1 m/s onto the first in the relative
//! orientation in which they ended 7–9 mm interpenetrated.

use std::path::PathBuf;
use std::sync::Arc;

use ballast::nscd::body::{Body, BodyShape, Motion};
use ballast::nscd::nlgs::{ErrorCheck, NlgsOptions, Stopping};
use ballast::nscd::step::{FrictionTable, MoreauJean, StepParams};
use nalgebra::{Point3, Translation3, Vector3};

fn points(v: &serde_json::Value) -> Vec<Point3<f64>> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let p: Vec<f64> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            Point3::new(p[0], p[1], p[2])
        })
        .collect()
}

/// The deepest interpenetration (m) over `steps` steps of `dt` of the stone falling at
/// 1 m/s from 12 mm above the fixed one (along their contact normal).
fn drop(dt: f64, steps: usize) -> f64 {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/edge_over_corner.json");
    let data: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let n = Vector3::from_vec(
        data["normal"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect(),
    );
    let hull = |key: &str| BodyShape::convex_hull(&points(&data[key]), key).unwrap();
    let fixed = hull("fixed");
    let falling = hull("falling");
    let mut bodies = vec![
        Body::fixed(
            "fixed",
            Arc::new(fixed.shape),
            0,
            fixed.pose,
            Motion::Static,
        ),
        Body::dynamic(
            "falling",
            Arc::new(falling.shape),
            2700.0,
            0,
            Translation3::from(0.012 * n) * falling.pose,
        ),
    ];
    bodies[1].velocity = -Vector3::z();
    // The deposit's settings (scenes/bed.toml) at its raining friction.
    let params = StepParams {
        dt,
        theta: 1.0,
        gravity: Vector3::new(0.0, 0.0, -9.81),
        alert_distance: 2e-3,
        depenetration_speed: 5e-3,
        period: None,
    };
    let options = NlgsOptions {
        stopping: Stopping::Tolerance {
            tolerance: 1e-4,
            max_sweeps: 100,
        },
        error_check: ErrorCheck::Light { every: 10 },
    };
    let mut engine = MoreauJean::new(params, options);
    let friction = FrictionTable::uniform(1, 0.2);
    let mut deepest: f64 = 0.0;
    for k in 0..steps {
        engine.step(&mut bodies, k as f64 * dt, &friction);
        let now = engine.detect(&bodies);
        deepest = now.iter().map(|c| -c.gap).fold(deepest, f64::max);
    }
    deepest
}

/// The falling stone's edge first meets an edge of the fixed one, slides along it onto
/// the corner's next edge and on down the side. That next pair of edges is a few
/// degrees short of a face of the Minkowski difference when the step begins, so it is
/// not a contact: the edge cuts 0.83 mm into the stone in one 2 ms step (0.26 mm at
/// 0.5 ms). Ignored because it fails: a fix that made such crossings of edge interiors
/// contacts passed it (no negative gap at either step; the bound is 20 µm) but was not
/// kept, as it turned `make`'s impact-quick bed into one that did not settle (a
/// 3.8 mm overlap; docs/nscd.md). `cargo test --release --test contact_edges --
/// --ignored` runs it.
#[test]
#[ignore = "known engine failure (issue #6, docs/nscd.md \"Edges over a corner\"): 0.83 mm; \
            the fix tried was not kept"]
fn an_edge_sliding_over_a_corner_does_not_cut_into_the_next_edge() {
    for (dt, steps) in [(2e-3, 30), (5e-4, 60)] {
        let deepest = drop(dt, steps);
        assert!(
            deepest < 2e-5,
            "dt {dt}: the stones interpenetrated by {:.3} mm",
            1e3 * deepest
        );
    }
}

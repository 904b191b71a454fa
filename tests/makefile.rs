//! The Makefile's rules name the meshes their tools read, so that one target made on a
//! fresh machine meshes what it needs first. make expands a rule's prerequisites as it
//! reads the rule: a mesh list defined in a fragment (mk/*.mk) read after the rule's
//! own was empty there, and `make results/bed-quick/summary.json` on a fresh machine ran
//! ballast-pack before any stone was meshed ("scenes/../meshes/stones: No such file").
//! `make -n -B TARGET` prints every command TARGET would run from nothing, without
//! running one.

use std::process::Command;

/// The commands `make -n -B target` prints in the project root.
fn dry_run(target: &str) -> String {
    let out = Command::new("make")
        .args(["--no-print-directory", "-n", "-B", target])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("make");
    assert!(
        out.status.success(),
        "make -n -B {target}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("make prints UTF-8")
}

/// Whether `commands` mesh `mesh` before they run `tool` (its first mention).
fn meshed_before(commands: &str, mesh: &str, tool: &str) -> bool {
    match (commands.find(&format!("-o {mesh}")), commands.find(tool)) {
        (Some(m), Some(t)) => m < t,
        _ => false,
    }
}

#[test]
fn every_bed_and_bench_meshes_the_stones_before_it_runs() {
    let first_stone = "meshes/stones/stone_001.msh";
    let last_stone = "meshes/stones/stone_060.msh";
    for (target, tool) in [
        (
            "results/bed-quick/summary.json",
            "ballast-pack scenes/bed.toml",
        ),
        (
            "results/bed-table3/summary.json",
            "ballast-pack scenes/bed.toml",
        ),
        (
            "results/bed-impact-quick/packing.toml",
            "ballast-pack scenes/bed.toml",
        ),
        ("bench-ddm", "ballast-pack scenes/bed.toml"),
        ("bench-nscd", "ballast-nscd scenes/"),
    ] {
        let commands = dry_run(target);
        for stone in [first_stone, last_stone] {
            assert!(
                meshed_before(&commands, stone, tool),
                "make {target} runs {tool} without meshing {stone} first"
            );
        }
    }
}

#[test]
fn the_seed_sized_beds_mesh_the_fine_sleeper_before_packing() {
    // The bed rule lists the 25 mm Type-3 mesh (the impact presets' sleeper, which
    // ballast-qdem reads) for every preset.
    for target in [
        "results/bed-table3/summary.json",
        "results/bed-impact/summary.json",
    ] {
        let commands = dry_run(target);
        assert!(
            meshed_before(
                &commands,
                "meshes/sleeper_type3_h0.025.msh",
                "ballast-pack scenes/bed.toml"
            ),
            "make {target} packs without meshing the 25 mm sleeper first"
        );
    }
}

#[test]
fn the_tamping7_bed_packs_its_bay_before_laying_it() {
    // `tile.bay` of the tamping7 preset reads results/bed-tamping7-bay/packing.toml.
    let commands = dry_run("results/bed-tamping7/summary.json");
    let bay = commands.find("--preset tamping7-bay");
    let tiled = commands.find("--preset tamping7 ");
    assert!(
        matches!((bay, tiled), (Some(b), Some(t)) if b < t),
        "make results/bed-tamping7/summary.json does not pack the bay first:\n{commands}"
    );
}

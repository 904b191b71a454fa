//! `ballast-pack SCENE.toml`: builds the bed of a [`BedScene`] and writes it.
//!
//! Output directory:
//! - `packing.toml`: the packing ([`super::packing`]), read by `ballast-nscd`;
//! - `stones.vtu`, `sleepers.vtu`: the final bed as triangulated surfaces (cell field
//!   `id`, point field `velocity_m_per_s`);
//! - `control_boxes.vtu`: the control boxes, cell field `compactness`;
//! - `bed.pvd` + `frames/bed_NNNN.vtu`: the deposition (stones and sleepers);
//! - `deposit.csv`: per step, phase, stones, contacts, NLGS sweeps and error, kinetic
//!   energy, interpenetration;
//! - `summary.json`: grains, d50, compactness per control box, interpenetration,
//!   coordination number, phases, wall times, grains·steps per second;
//! - `checkpoint.bin` every `output.checkpoint_every` steps and after
//!   `output.checkpoint_wall_every` of wall time, from which
//!   `ballast-pack … --resume DIR` continues a killed run ([`super::resume`]).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde_json::json;

use super::contacts::{contacts_csv, packed_contacts, BodyRef, CONTACTS_FILE};
use super::deposit::{bounds, DepositSetup, Deposition, Observer, Role, SleeperModel};
use super::packing::{PackedMesh, Packing, Placement, PACKING_FORMAT};
use super::profile::Profile;
use super::recorder::{CheckpointPlan, Recorder, WeightWatch};
use super::report::{
    compactness, control_boxes, coordination_numbers, interpenetration, median, stone_bodies,
    stones_outside, BoxProfile, Compactness, PROFILE_SLICE_OVER_D50,
};
use super::resume::{restore_from, PackCheckpoint};
use super::scene::{BedScene, CompactionStage};
use super::tile::{lay_bay, Laid, SceneSleeper, Target};
use crate::ddm::Partitioning;
use crate::geometry::{ControlBox, Period};
use crate::nscd::body::{Body, BodyShape};
use crate::nscd::motion::{mesh_pieces, Pieces};
use crate::nscd::run::{grains_grid, Drawn};
use crate::nscd::scene::{read_stone_shapes, NscdScene, StoneShape};
use crate::nscd::step::{FrictionTable, StepParams};
use crate::output::{write_atomic, write_json, write_vtu, Cadence, Grid, CHECKPOINT_FILE};
use crate::scene::{PhaseTimer, RunContext, Summary};
use crate::{Error, Result};

/// Default `deposit.max_overlap` over the family's d50: half the acceptance bound of
/// 0.1 % (the final measure comes one step after the last check).
pub const DEFAULT_OVERLAP_OVER_D50: f64 = 5e-4;

/// A sleeper model and how its placement frame sits in its mesh (or cuboid) frame.
struct SleeperSource {
    model: SleeperModel,
    /// Own frame (footprint centred, underside at z = 0) from the mesh frame.
    own_from_mesh: Isometry3<f64>,
    mesh: Option<std::path::PathBuf>,
    size: Option<[f64; 3]>,
}

fn sleeper_source(scene: &BedScene, scene_path: &Path) -> Result<Option<SleeperSource>> {
    let Some(spec) = &scene.sleepers else {
        return Ok(None);
    };
    let density = scene.density(&spec.material);
    let material = scene.material_index(&spec.material);
    if let Some(size) = &spec.size {
        let size = Vector3::new(size[0].si(), size[1].si(), size[2].si());
        let shape = BodyShape::cuboid(size)
            .map_err(|e| Error::invalid(scene_path, format!("key sleepers.size: {e}")))?;
        let lift = Isometry3::translation(0.0, 0.0, 0.5 * size.z);
        return Ok(Some(SleeperSource {
            model: SleeperModel {
                shape: Arc::new(shape),
                frame: lift,
                footprint: [size.x, size.y],
                density,
                material,
                level: spec.level,
            },
            own_from_mesh: lift,
            mesh: None,
            size: Some([size.x, size.y, size.z]),
        }));
    }
    let file = NscdScene::resolve(scene_path, spec.mesh.as_ref().expect("validated"));
    let mesh = crate::mesh::read_msh(&file)
        .map_err(|e| Error::invalid(scene_path, format!("key sleepers.mesh: {e}")))?;
    let pieces = mesh_pieces(&mesh, &Pieces::Hull)
        .map_err(|e| Error::invalid(scene_path, format!("key sleepers.mesh: {e}")))?;
    let points = &pieces[0].1;
    let (lo, hi) = bounds(points);
    // The sleeper lies across the track (y): a mesh longer in x is turned about z.
    let turn = if hi.x - lo.x > hi.y - lo.y {
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2)
    } else {
        UnitQuaternion::identity()
    };
    let centre = Vector3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), lo.z);
    let own_from_mesh = Isometry3::from_parts(Translation3::from(-(turn * centre)), turn);
    let own: Vec<Point3<f64>> = points.iter().map(|p| own_from_mesh * p).collect();
    let mut principal =
        BodyShape::convex_hull(&own, &format!("key sleepers.mesh: {}", file.display())).map_err(
            |e| match e {
                Error::Message(m) => Error::invalid(scene_path, m),
                e => e,
            },
        )?;
    if let Some(d) = scene.stones.spheres.filter(|d| d.si() > 0.0) {
        principal.with_vertex_spheres(&mesh, &own_from_mesh, 1.0, d.si());
    }
    let extent = turn * (hi - lo);
    Ok(Some(SleeperSource {
        model: SleeperModel {
            shape: Arc::new(principal.shape),
            frame: principal.pose,
            footprint: [extent.x.abs(), extent.y.abs()],
            density,
            material,
            level: spec.level,
        },
        own_from_mesh,
        mesh: Some(file),
        size: None,
    }))
}

/// The scene's track-bed profile: crest half-width from the sleepers' footprint (known
/// only once a sleeper mesh is read) plus the shoulder width, top at the crib level.
fn profile_of(
    scene: &BedScene,
    sleeper: Option<&SleeperSource>,
    crib_top: f64,
    scene_path: &Path,
) -> Result<Option<Profile>> {
    let (Some(width), Some(slope), Some(source)) =
        (scene.bed.shoulder_width, scene.bed.shoulder_slope, sleeper)
    else {
        return Ok(None);
    };
    let profile = Profile {
        crest_half_width: 0.5 * source.model.footprint[1] + width.si(),
        slope,
        top: crib_top,
    };
    if 2.0 * profile.crest_half_width >= scene.bed.width.si() {
        return Err(Error::invalid(
            scene_path,
            format!(
                "key bed.shoulder_width: the crest (sleeper length {:.3} m + 2 × shoulder) is \
                 {:.3} m, not less than bed.width {:.3} m",
                source.model.footprint[1],
                2.0 * profile.crest_half_width,
                scene.bed.width.si()
            ),
        ));
    }
    Ok(Some(profile))
}

/// A periodic bed must be long enough that two bodies meet through one image at most
/// (the condition of [`crate::contact::candidate_pairs`]): a body reaches both ends of
/// another only if their extents along x, plus the alert distance and how far they
/// move in a step, add up to the length. Checked with the sleeper's footprint and the
/// largest stone's bounding diameter, a quarter of that diameter for the alert
/// distance and the reach (a few mm each at the deposit's time steps), and two stones.
fn check_period(
    scene: &BedScene,
    family: &[StoneShape],
    sleeper: Option<&SleeperSource>,
    scene_path: &Path,
) -> Result<()> {
    let stone = family.iter().map(|s| 2.0 * s.radius()).fold(0.0, f64::max);
    let sleeper_x = sleeper.map_or(0.0, |s| s.model.footprint[0]);
    let needed = (2.5 * stone).max(sleeper_x + 1.25 * stone);
    let length = scene.bed.length.si();
    if length <= needed {
        return Err(Error::invalid(
            scene_path,
            format!(
                "key bed.length: a periodic bed must be longer than {needed:.3} m (the \
                 sleeper's {sleeper_x:.3} m along x plus 1.25 × the largest stone, \
                 {stone:.3} m across, or 2.5 stones), not {length} m"
            ),
        ));
    }
    Ok(())
}

/// The bay of `[tile]` read from `path` and laid along the bed ([`super::tile`]).
fn lay_tiles(
    scene: &BedScene,
    path: &Path,
    setup: &DepositSetup,
    sleeper: Option<&SleeperSource>,
    first_sleeper: Option<f64>,
    crib_top: f64,
) -> Result<Laid> {
    let bay = Packing::read(path)?;
    if bay.settled == Some(false) {
        println!(
            "ballast-pack: the bay {} did not settle (its last phase ran to its cap); the \
             tiled bed starts from it as it is",
            path.display()
        );
    }
    let scene_sleeper = match (sleeper, &scene.sleepers, first_sleeper) {
        (Some(source), Some(spec), Some(first)) => Some(SceneSleeper {
            model: &source.model,
            own_from_mesh: source.own_from_mesh,
            inertia_scale: setup.sleeper_inertia_scale,
            size: source.size,
            mesh: source.mesh.as_deref(),
            spacing: spec.spacing.si(),
            first,
            count: spec.count,
        }),
        _ => None,
    };
    let laid = lay_bay(
        &bay,
        path,
        &Target {
            family: &setup.family,
            stone: (setup.stone_density, setup.stone_material),
            sleeper: scene_sleeper,
            size: [setup.length, setup.width],
            periodic: setup.params.period.is_some(),
            crib_top,
        },
    )?;
    println!(
        "ballast-pack: tiled {} ({} stones a bay) into {} stones, {} copies left out at the \
         end walls",
        path.display(),
        laid.bay_stones,
        laid.bodies.len() - laid.sleepers(),
        laid.dropped
    );
    Ok(laid)
}

fn friction_tables(scene: &BedScene) -> (FrictionTable, FrictionTable) {
    let mut table = FrictionTable::uniform(scene.material.len(), 0.0);
    for f in &scene.friction {
        table.set(
            scene.material_index(&f.pair[0]),
            scene.material_index(&f.pair[1]),
            f.mu,
        );
    }
    let mut raining = table.clone();
    if let Some(mu) = scene.deposit.friction {
        let s = scene.material_index(&scene.stones.material);
        raining.set(s, s, mu);
    }
    (table, raining)
}

/// Runs the scene of `ctx`; with `resume`, from the checkpoint in the output directory
/// (written by a run of the same scene, preset and overrides).
pub fn run(ctx: &RunContext, resume: bool) -> Result<()> {
    let threads = ctx.configure_threads()?;
    let mut timer = PhaseTimer::new();
    let (scene, inputs): (BedScene, _) = timer.time("read scene", || ctx.load_scene())?;
    let scene_text = toml::to_string(&inputs)
        .map_err(|e| Error::Message(format!("cannot write the merged scene: {e}")))?;
    let checkpoint_path = ctx.out_dir.join(CHECKPOINT_FILE);
    let resumed = if resume {
        Some(PackCheckpoint::read(&checkpoint_path, &scene_text)?)
    } else {
        None
    };
    let directory = NscdScene::resolve(&ctx.scene_path, &scene.stones.directory);
    let round = scene.stones.round.map_or(0.0, |r| r.si());
    let spheres = scene.stones.spheres.map_or(0.0, |d| d.si());
    if round > 0.0 {
        println!("ballast-pack: stones.round is experimental (docs/pack.md, \"Rounded stones\")");
    }
    let family: Vec<StoneShape> = timer
        .time("read stones", || {
            read_stone_shapes(&directory, scene.stones.scale)
        })?
        .into_iter()
        .map(|s| s.rounded(round).with_vertex_spheres(spheres))
        .collect();
    if family.is_empty() {
        return Err(Error::invalid(
            &ctx.scene_path,
            format!(
                "key stones.directory: no stone_*.msh in {} (make meshes builds them)",
                directory.display()
            ),
        ));
    }
    let smallest = family
        .iter()
        .map(|s| 2.0 * s.radius())
        .fold(f64::INFINITY, f64::min);
    for (key, extent) in [
        ("bed.length", scene.bed.length.si()),
        ("bed.width", scene.bed.width.si()),
    ] {
        if extent < smallest {
            return Err(Error::invalid(
                &ctx.scene_path,
                format!(
                    "key {key}: {extent} m is narrower than the smallest stone of the family \
                     ({smallest:.4} m across its bounding sphere): no stone fits"
                ),
            ));
        }
    }
    let sleeper = sleeper_source(&scene, &ctx.scene_path)?;
    let period = scene.periodic().then(|| Period {
        axis: 0,
        low: 0.0,
        length: scene.bed.length.si(),
    });
    if period.is_some() {
        check_period(&scene, &family, sleeper.as_ref(), &ctx.scene_path)?;
    }
    let (friction, rain_friction) = friction_tables(&scene);
    let d = &scene.deposit;
    let family_d50 = median(&family.iter().map(StoneShape::diameter).collect::<Vec<_>>());
    let nominal: Vec<[f64; 2]> = match &scene.sleepers {
        Some(s) => (0..s.count)
            .map(|k| {
                let x = 0.5 * scene.bed.length.si()
                    + (k as f64 - 0.5 * (s.count as f64 - 1.0)) * s.spacing.si();
                [x, 0.0]
            })
            .collect(),
        None => Vec::new(),
    };
    // The seed's partition: one slab per sleeper, cut midway between neighbours (two
    // equal slabs without sleepers); the scene's [deposit.ddm] may give another.
    let (length, width) = (scene.bed.length.si(), scene.bed.width.si());
    let per_sleeper = if nominal.len() >= 2 {
        Partitioning::Slabs {
            axis: 0,
            cuts: nominal
                .windows(2)
                .map(|w| 0.5 * (w[0][0] + w[1][0]))
                .collect(),
        }
    } else {
        Partitioning::even_slabs(0, 0.0, length, 2)
    };
    let ddm = d
        .ddm
        .setup([0.0, length, -0.5 * width, 0.5 * width], &[], per_sleeper);
    let depth = scene.bed.depth.si();
    let crib_top = scene
        .sleepers
        .as_ref()
        .map_or(depth, |s| depth + s.embed.si());
    let profile = profile_of(&scene, sleeper.as_ref(), crib_top, &ctx.scene_path)?;
    let stone_density = scene.density(&scene.stones.material);
    let sleeper_inertia_scale = sleeper.as_ref().map_or(1.0, |s| {
        DepositSetup::inertia_scale(&family, stone_density, s.model.mass(), d.sleeper_mass_ratio)
    });
    let setup = DepositSetup {
        family,
        stone_density,
        stone_material: scene.material_index(&scene.stones.material),
        length: scene.bed.length.si(),
        width: scene.bed.width.si(),
        wall_material: scene.material_index(&scene.bed.wall_material),
        params: StepParams {
            dt: d.dt.si(),
            theta: d.theta,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            alert_distance: d.alert_distance.si(),
            depenetration_speed: d.depenetration_speed.map_or(0.0, |v| v.si()),
            period,
            end_checks: d.end_checks,
        },
        tolerance: d.tolerance,
        max_sweeps: d.max_sweeps,
        finish_sweeps: d.finish_sweeps,
        held_warm_start: d.held_warm_start,
        friction,
        rain_friction,
        settle_speed: d.settle_speed.si(),
        max_overlap: d
            .max_overlap
            .map_or_else(|| DEFAULT_OVERLAP_OVER_D50 * family_d50, |l| l.si()),
        max_phase_time: d.max_phase_time.si(),
        max_stones: scene.stones.count.unwrap_or(usize::MAX),
        drag_time: d.drag_time.map(|t| t.si()),
        seed: scene.seed,
        ddm,
        profile,
        sleeper_inertia_scale,
        hold_sleepers: d.hold_sleepers,
        release_sleepers: d.release_sleepers,
    };
    let placed: Vec<(SleeperModel, [f64; 2])> = match &sleeper {
        Some(source) => nominal
            .iter()
            .map(|xy| (source.model.clone(), *xy))
            .collect(),
        None => Vec::new(),
    };
    let laid = match &scene.tile {
        Some(tile) => Some(lay_tiles(
            &scene,
            &NscdScene::resolve(&ctx.scene_path, &tile.bay),
            &setup,
            sleeper.as_ref(),
            nominal.first().map(|xy| xy[0]),
            crib_top,
        )?),
        None => None,
    };
    let mut bed = match &resumed {
        Some(c) => {
            let models: Vec<SleeperModel> = placed.iter().map(|(m, _)| m.clone()).collect();
            restore_from(&checkpoint_path, setup, &c.bed, &models)?
        }
        None => Deposition::new(setup),
    };
    std::fs::create_dir_all(ctx.out_dir.join("frames")).map_err(|e| Error::io(&ctx.out_dir, e))?;
    println!(
        "ballast-pack: {} — bed {:.3} × {:.3} m, {} stone shapes (largest {:.1} mm across), {} sleepers, \
         seed {}, {threads} threads",
        ctx.scene_path.display(),
        scene.bed.length.si(),
        scene.bed.width.si(),
        bed.setup.family.len(),
        1e3 * bed.cell() / 1.01,
        scene.sleepers.as_ref().map_or(0, |s| s.count),
        scene.seed,
    );
    if bed.setup.sleeper_inertia_scale > 1.0 {
        println!(
            "ballast-pack: sleepers packed with 1/{:.2} of their inertia \
             (deposit.sleeper_mass_ratio = {}), their full weight",
            bed.setup.sleeper_inertia_scale, d.sleeper_mass_ratio
        );
    }

    let gravity = bed.setup.params.gravity.norm();
    let watch = WeightWatch {
        sleepers_n: scene.sleepers.as_ref().map_or(0, |s| s.count) as f64
            * sleeper.as_ref().map_or(0.0, |s| s.model.mass())
            * gravity,
        gravity,
        held_warm_start: d.held_warm_start,
    };
    let mut recorder = Recorder::open(
        &ctx.out_dir,
        scene.output.frame_interval.si(),
        CheckpointPlan {
            path: checkpoint_path.clone(),
            cadence: Cadence::new(
                scene.output.checkpoint_every,
                scene.output.checkpoint_wall_every,
            ),
            scene: scene_text,
        },
        watch,
        resumed.as_ref(),
    )?;
    if let Some(c) = &resumed {
        println!(
            "ballast-pack: resumed from {} at step {} (t = {:.4} s)",
            checkpoint_path.display(),
            c.bed.steps,
            c.bed.time
        );
    }

    let compact = |bed: &mut Deposition, observe: &mut dyn Observer| {
        if let Some(c) = &scene.compaction {
            bed.compact(c.amplitude.si(), c.frequency.si(), c.duration.si(), observe);
        }
    };
    let stage = scene.compaction.as_ref().map(|c| c.stage);
    // The stages; a resumed bed skips those done before its checkpoint.
    let observe = &mut recorder;
    if let Some(laid) = laid {
        bed.lay("tile", laid);
    } else if sleeper.is_some() {
        bed.fill("under-sleeper layer", 0.0, depth, true, observe);
        if stage == Some(CompactionStage::Layer) {
            compact(&mut bed, observe);
        }
        bed.lower_sleepers(&placed, observe);
        bed.fill("crib", depth, crib_top, true, observe);
    } else {
        bed.fill("bed", 0.0, depth, true, observe);
    }
    // Compaction of the finished bed and the final settle run under gravity and
    // contact alone, and the final state has no body moving.
    bed.finish();
    if stage == Some(CompactionStage::Bed) || (sleeper.is_none() && stage.is_some()) {
        compact(&mut bed, observe);
    }
    let lifts = bed.hold_sleepers();
    if !lifts.is_empty() {
        let microns: Vec<String> = lifts.iter().map(|l| format!("{:.1}", 1e6 * l)).collect();
        println!(
            "ballast-pack: sleepers held for the final settle, lifted clear of the stones \
             under them by [{}] µm",
            microns.join(", ")
        );
    }
    bed.settle("final settle", observe);
    let models: Vec<SleeperModel> = placed.iter().map(|(m, _)| m.clone()).collect();
    bed.release_sleepers(&models, observe);
    recorder.finish()?;
    let wall_deposit = recorder.wall();
    for (name, t) in ["detect", "build", "solve", "update"]
        .iter()
        .zip(bed.phase_times)
    {
        timer.add(name, t);
    }
    if bed.setup.ddm.is_some() {
        timer.add("solve: subdomains (parallel)", bed.solve_split[0]);
        timer.add("solve: interface (sequential)", bed.solve_split[1]);
    }
    timer.add("checkpoints", recorder.checkpoint_time);
    let other = wall_deposit.saturating_sub(bed.stepping + recorder.checkpoint_time);
    timer.add("frames and csv", other);

    // Measures of the final bed.
    let clock = Instant::now();
    let final_contacts = bed.detect();
    let (max_pen, mean_pen) = interpenetration(&final_contacts);
    // Where the deepest overlap is: the bed's body indices and roles, and the point to
    // find it in ParaView.
    let deepest = final_contacts
        .iter()
        .min_by(|a, b| a.gap.total_cmp(&b.gap))
        .filter(|c| c.gap < 0.0)
        .map(|c| {
            let (a, b) = (c.key.body_a as usize, c.key.body_b as usize);
            json!({
                "bodies": [a, b],
                "roles": [format!("{:?}", bed.roles[a]), format!("{:?}", bed.roles[b])],
                "point_m": [c.point.x, c.point.y, c.point.z],
                "normal": [c.normal.x, c.normal.y, c.normal.z],
                "depth_m": -c.gap,
            })
        });
    let (coordination, coordination_walls) = coordination_numbers(&bed.roles, bed.last_contacts());
    let diameters = bed.stone_diameters();
    if diameters.is_empty() {
        return Err(Error::invalid(
            &ctx.scene_path,
            "no stone could be placed in the bed (all plan positions fell on sleepers or \
             too close to the walls); only deposit.csv and the frames were written",
        ));
    }
    let d50 = median(&diameters);
    let sleeper_boxes = bed.sleeper_boxes();
    let mut boxes = control_boxes(
        bed.setup.length,
        bed.setup.width,
        depth,
        &sleeper_boxes,
        crib_top,
        d50,
        bed.setup.params.period.is_some(),
    );
    if let Some(p) = &bed.setup.profile {
        // The whole-bed box stays under the slopes too, one d50 in from them.
        for (_, b) in boxes.iter_mut().filter(|(name, _)| name == "bed") {
            let half = p.half_width_at(b.max.z) - d50;
            b.min.y = b.min.y.max(-half);
            b.max.y = b.max.y.min(half);
        }
    }
    if let Some((name, _)) = boxes.iter().find(|(_, b)| b.volume() <= 0.0) {
        return Err(Error::invalid(
            &ctx.scene_path,
            format!(
                "control box {name} is empty: the boxes stay one d50 ({d50:.4} m) clear of the \
                 walls, the floor and the crib surface, and this bed leaves no room for it \
                 (make bed.length, bed.width, bed.depth or sleepers.embed larger)"
            ),
        ));
    }
    let solid = compactness(
        &bed.bodies,
        &bed.roles,
        &boxes,
        bed.setup.params.period.as_ref(),
    );
    let profiles = under_sleeper_profiles(&bed, &solid, d50);
    let top = bed
        .bodies
        .iter()
        .zip(&bed.roles)
        .filter(|(_, r)| matches!(r, Role::Stone(_)))
        .flat_map(|(b, _)| b.world_vertices())
        .map(|p| p.z)
        .fold(0.0, f64::max);
    let container = ControlBox {
        min: Point3::new(0.0, -0.5 * bed.setup.width, bed.floor_offset().min(0.0)),
        max: Point3::new(bed.setup.length, 0.5 * bed.setup.width, f64::INFINITY),
    };
    let outside = stones_outside(&bed.bodies, &bed.roles, &container);
    // How far the highest stone centre stands above the profile (≤ 0 after the
    // strike-off, unless the settle lifted one).
    let profile_json = bed.setup.profile.map(|p| {
        let excess = bed
            .bodies
            .iter()
            .zip(&bed.roles)
            .filter(|(_, r)| matches!(r, Role::Stone(_)))
            .map(|(b, _)| b.position.z - p.height(b.position.y))
            .fold(f64::NEG_INFINITY, f64::max);
        json!({
            "crest_half_width_m": p.crest_half_width, "slope": p.slope, "top_m": p.top,
            "toe_m": p.toe(), "max_centre_above_m": excess,
        })
    });
    timer.add("measures", clock.elapsed());

    // Files.
    let clock = Instant::now();
    let settled = bed.at_rest();
    let mut packing = packing_of(
        &scene,
        &bed,
        sleeper.as_ref(),
        d50,
        crib_top.max(top),
        &ctx.out_dir,
    )?;
    packing.crib_top_m = Some(crib_top);
    packing.settled = Some(settled);
    packing.capped_phases = bed.capped_phases().into_iter().map(String::from).collect();
    // The last step's impulses at the final configuration, for a warm restart.
    let contacts = packed_contacts(&final_contacts, bed.last_contacts(), &body_refs(&bed.roles));
    write_atomic(
        ctx.out_dir.join(CONTACTS_FILE),
        contacts_csv(&contacts).as_bytes(),
    )?;
    packing.contacts = Some(CONTACTS_FILE.into());
    packing.write(&ctx.out_dir.join("packing.toml"))?;
    let (stones, sleepers) = split(&bed.bodies, &bed.roles);
    write_vtu(
        ctx.out_dir.join("stones.vtu"),
        &grains_grid(&stones, Drawn::All, &[])?,
    )?;
    if !sleepers.is_empty() {
        write_vtu(
            ctx.out_dir.join("sleepers.vtu"),
            &grains_grid(&sleepers, Drawn::All, &[])?,
        )?;
    }
    write_vtu(ctx.out_dir.join("control_boxes.vtu"), &boxes_grid(&solid)?)?;
    recorder.frame(bed.time, &bed.bodies, &bed.roles)?;
    timer.add("output", clock.elapsed());

    let stepping = bed.stepping.as_secs_f64();
    let capped = bed.capped_phases();
    let phases: Vec<serde_json::Value> = bed
        .phases
        .iter()
        .map(|p| {
            json!({
                "name": p.name, "time_s": p.time, "steps": p.steps, "settled": p.settled,
                "inserted": p.inserted, "removed": p.removed,
                "sleeper_support_over_weight": p.sleeper_support,
            })
        })
        .collect();
    let compactness_json: Vec<serde_json::Value> = solid
        .iter()
        .map(|c| {
            json!({
                "box": c.name, "value": c.value,
                "min_m": [c.bx.min.x, c.bx.min.y, c.bx.min.z],
                "max_m": [c.bx.max.x, c.bx.max.y, c.bx.max.z],
            })
        })
        .collect();
    let summary = Summary::new(ctx, &inputs)
        .figure("grains", diameters.len())
        .figure("sleepers", sleepers.len())
        .figure("d50_m", d50)
        .figure("compactness", compactness_json)
        .figure(
            "compactness_profiles",
            serde_json::to_value(&profiles).expect("profiles are plain numbers"),
        )
        .figure("max_interpenetration_m", max_pen)
        .figure("deepest_overlap", deepest)
        .figure("mean_interpenetration_m", mean_pen)
        .figure("max_interpenetration_over_d50", max_pen / d50)
        .figure("mean_interpenetration_over_d50", mean_pen / d50)
        .figure("coordination_number", coordination)
        .figure("coordination_number_with_boundaries", coordination_walls)
        .figure("stones_outside", outside)
        .figure("profile", profile_json)
        .figure("bed_top_m", top)
        .figure("floor_offset_m", bed.floor_offset())
        .figure("sleeper_inertia_scale", bed.setup.sleeper_inertia_scale)
        .figure("bed_weight_N", watch.bed_weight(&bed.bodies, &bed.roles))
        .figure("settled", settled)
        .figure("capped_phases", capped.clone())
        .figure("phases", phases)
        .figure("steps", bed.steps)
        .figure("simulated_time_s", bed.time)
        .figure("stepping_s", stepping)
        .figure(
            "grains_steps_per_s",
            bed.body_steps as f64 / stepping.max(1e-12),
        )
        .figure("seed", scene.seed)
        .figure("threads", threads)
        .wall_times(&timer);
    write_json(ctx.out_dir.join("summary.json"), &summary.to_json())?;
    println!(
        "ballast-pack: {} stones (d50 {:.1} mm), {} sleepers, {} steps ({:.2} s simulated) in \
         {stepping:.1} s, {:.3e} grains·steps/s{}",
        diameters.len(),
        1e3 * d50,
        sleepers.len(),
        bed.steps,
        bed.time,
        bed.body_steps as f64 / stepping.max(1e-12),
        if settled {
            ""
        } else {
            " — NOT SETTLED (see summary.json phases)"
        }
    );
    if !capped.is_empty() {
        println!(
            "ballast-pack: phases run to their cap (deposit.max_phase_time) without \
             settling: {}{}",
            capped.join(", "),
            if settled {
                " (the last phase settled: the bed is at rest by its test, but may still creep)"
            } else {
                ""
            }
        );
    }
    println!(
        "ballast-pack: interpenetration max {:.2e} m ({:.3} % d50), mean {:.2e} m; \
         coordination {coordination:.2}; {outside} stones outside",
        max_pen,
        100.0 * max_pen / d50,
        mean_pen
    );
    for c in &solid {
        println!("ballast-pack: compactness {:<18} {:.4}", c.name, c.value);
    }
    for p in &profiles {
        println!("ballast-pack: {}", p.line());
    }
    println!(
        "ballast-pack: wrote {}",
        ctx.out_dir.join("packing.toml").display()
    );
    Ok(())
}

/// The solid fraction under each sleeper by depth below its underside, in slices of
/// [`PROFILE_SLICE_OVER_D50`] d50, and below its top d50 ([`BoxProfile::measure`]).
fn under_sleeper_profiles(bed: &Deposition, solid: &[Compactness], d50: f64) -> Vec<BoxProfile> {
    let stones = stone_bodies(&bed.bodies, &bed.roles);
    solid
        .iter()
        .filter(|c| c.name.starts_with("under_sleeper"))
        .map(|c| {
            BoxProfile::measure(
                &stones,
                &c.name,
                &c.bx,
                PROFILE_SLICE_OVER_D50 * d50,
                d50,
                bed.setup.params.period.as_ref(),
            )
        })
        .collect()
}

/// Stones and sleepers as two body lists (for their VTK files).
fn split(bodies: &[Body], roles: &[Role]) -> (Vec<Body>, Vec<Body>) {
    let pick = |want: fn(&Role) -> bool| {
        bodies
            .iter()
            .zip(roles)
            .filter(|(_, r)| want(r))
            .map(|(b, _)| b.clone())
            .collect::<Vec<_>>()
    };
    (
        pick(|r| matches!(r, Role::Stone(_))),
        pick(|r| matches!(r, Role::Sleeper(_))),
    )
}

/// The control boxes as closed triangulated surfaces with their compactness.
fn boxes_grid(boxes: &[Compactness]) -> Result<Grid> {
    // Corner k has x from bit 0, y from bit 1, z from bit 2; two triangles per face.
    const FACES: [[usize; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut points = Vec::new();
    let mut triangles = Vec::new();
    let mut values = Vec::new();
    for c in boxes {
        let base = points.len();
        for k in 0..8 {
            points.push([
                if k & 1 == 0 { c.bx.min.x } else { c.bx.max.x },
                if k & 2 == 0 { c.bx.min.y } else { c.bx.max.y },
                if k & 4 == 0 { c.bx.min.z } else { c.bx.max.z },
            ]);
        }
        for f in FACES {
            triangles.push([base + f[0], base + f[1], base + f[2]]);
            triangles.push([base + f[0], base + f[2], base + f[3]]);
            values.extend([c.value, c.value]);
        }
    }
    let mut grid = Grid::triangles(points, &triangles)?;
    grid.add_cell_field("compactness", 1, values)?;
    Ok(grid)
}

/// The packing's name for each body: walls, sleepers and stones each numbered in body
/// order, as [`packing_of`] lists them.
fn body_refs(roles: &[Role]) -> Vec<BodyRef> {
    let mut counts = [0usize; 3];
    roles
        .iter()
        .map(|r| {
            let (slot, make): (usize, fn(usize) -> BodyRef) = match r {
                Role::Boundary => (0, BodyRef::Wall),
                Role::Sleeper(_) => (1, BodyRef::Sleeper),
                Role::Stone(_) => (2, BodyRef::Stone),
            };
            counts[slot] += 1;
            make(counts[slot] - 1)
        })
        .collect()
}

/// The packing file's content: mesh paths relative to the output directory.
fn packing_of(
    scene: &BedScene,
    bed: &Deposition,
    sleeper: Option<&SleeperSource>,
    d50: f64,
    top: f64,
    out_dir: &Path,
) -> Result<Packing> {
    let relative = |file: &Path| -> Result<std::path::PathBuf> {
        let absolute = std::fs::canonicalize(file).map_err(|e| Error::io(file, e))?;
        let base = std::fs::canonicalize(out_dir).map_err(|e| Error::io(out_dir, e))?;
        Ok(relative_path(&absolute, &base))
    };
    let mut meshes = Vec::new();
    for stone in &bed.setup.family {
        meshes.push(PackedMesh {
            file: relative(&stone.file)?,
            scale: stone.scale,
            round_m: stone.round(),
            spheres_m: stone.spheres(),
        });
    }
    let sleeper_mesh = match sleeper.and_then(|s| s.mesh.as_ref()) {
        Some(file) => {
            meshes.push(PackedMesh {
                file: relative(file)?,
                scale: 1.0,
                round_m: 0.0,
                spheres_m: sleeper.map_or(0.0, |s| s.model.shape.collider.sphere_diameter()),
            });
            Some(meshes.len() - 1)
        }
        None => None,
    };
    let mut stones = Vec::new();
    let mut sleepers = Vec::new();
    for (body, role) in bed.bodies.iter().zip(&bed.roles) {
        match role {
            Role::Stone(f) => {
                let pose = body.pose() * bed.setup.family[*f].mesh_pose.inverse();
                stones.push(Placement::from_pose(Some(*f), None, &pose));
            }
            Role::Sleeper(_) => {
                let source = sleeper.expect("sleepers come from a source");
                let pose = body.pose() * source.model.frame.inverse() * source.own_from_mesh;
                sleepers.push(Placement::from_pose(sleeper_mesh, source.size, &pose));
            }
            Role::Boundary => {}
        }
    }
    Ok(Packing {
        format: PACKING_FORMAT.to_string(),
        seed: scene.seed,
        d50_m: d50,
        container_min: [0.0, -0.5 * bed.setup.width, 0.0],
        container_max: [bed.setup.length, 0.5 * bed.setup.width, top],
        sides: scene.bed.sides.clone(),
        crib_top_m: None,
        settled: None,
        capped_phases: Vec::new(),
        contacts: None,
        meshes,
        stones,
        sleepers,
    })
}

/// `path` relative to `base` (both absolute, canonical).
fn relative_path(path: &Path, base: &Path) -> std::path::PathBuf {
    let p: Vec<_> = path.components().collect();
    let b: Vec<_> = base.components().collect();
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = std::path::PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &p[common..] {
        out.push(c);
    }
    out
}

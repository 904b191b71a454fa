//! From a packing to a [`MultiBody`]: the sleeper and the deformable stones merged into
//! one QDEM model (sleeper first, so its nodes are `0..sleeper_nodes`), the other
//! stones rigid; spheres at every surface vertex; the container's floor (and the walls
//! across a periodic direction) as planes; the rail-seat loads on the sleeper's
//! `rail_seat_1` (Rp1) and `rail_seat_2` (Rp2) groups, and the rails' hold on them.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::loads::RailSeatLoads;
use super::scene::{Periodic, RestPairs, SensorOn, SphereCentres, StoneModel, TrackScene};
use crate::dem::{
    BodyKind, ContactLaw, MultiBody, Period, Plane, RigidShape, SphereAt, SphereMaterial, SphereSet,
};
use crate::mesh::{read_msh, TetMesh};
use crate::pack::Packing;
use crate::qdem::{Boundary, GroupSpring, NodalLoad, QdemMaterial, QdemModel, TimeFunction};
use crate::{Error, Result};

/// A node sphere while building: (node, material, owner body, deformable index,
/// (inset, radius)).
type NodeSphere = (u32, u16, u32, u32, ([f64; 3], f64));

/// Material indices of the sphere law table.
pub const SLEEPER: u16 = 0;
/// Deformable ballast.
pub const BALLAST: u16 = 1;
/// Rigid ballast (same springs, plus the dashpot standing in for the viscosity).
pub const RIGID_BALLAST: u16 = 2;
/// Floor and walls.
pub const BASE: u16 = 3;

/// A built track: the system and what the run needs to read it.
#[derive(Debug)]
pub struct Track {
    /// The bodies.
    pub system: MultiBody,
    /// Nodes of the sleeper in the merged model: `0..sleeper_nodes`.
    pub sleeper_nodes: usize,
    /// Tetra of every deformable body, in merged node numbering (for VTK).
    pub tets: Vec<[u32; 4]>,
    /// Body id of each tetra (0 = sleeper).
    pub tet_body: Vec<u32>,
    /// Surface triangles of each rigid stone, indexing `rigid_vertices` (for VTK).
    pub rigid_triangles: Vec<Vec<[u32; 3]>>,
    /// Surface vertices of each rigid stone in its principal frame (m).
    pub rigid_vertices: Vec<Vec<[f64; 3]>>,
    /// Number of deformable stones.
    pub deformable_stones: usize,
    /// The sensors, resolved.
    pub sensors: Vec<Sensor>,
    /// The sleeper's bottom nodes (settlement = their mean vertical displacement).
    pub sleeper_bottom: Vec<u32>,
    /// Mean diameter of the stones' equivalent spheres (m).
    pub stone_size: f64,
}

/// A resolved sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Name.
    pub name: String,
    /// What it follows.
    pub at: SensorAt,
}

/// What a sensor follows.
#[derive(Debug, Clone, PartialEq)]
pub enum SensorAt {
    /// A node of the merged model.
    Node(u32),
    /// The mass centre of a deformable stone (its nodes).
    DeformableStone(std::ops::Range<u32>),
    /// The mass centre of rigid body `index`.
    RigidStone(u32),
}

/// Builds the track of `scene` (read from `scene_path`) on `packing` (read from
/// `packing_path`), with the rail-seat loads (shifted by the settling time).
pub fn build(
    scene_path: &Path,
    scene: &TrackScene,
    packing_path: &Path,
    packing: &Packing,
    loads: Option<&RailSeatLoads>,
) -> Result<Track> {
    let [sleeper_place] = packing.sleepers.as_slice() else {
        return Err(Error::invalid(
            packing_path,
            format!(
                "the track scene needs exactly one sleeper, the packing has {}",
                packing.sleepers.len()
            ),
        ));
    };
    let Some(sleeper_mesh_index) = sleeper_place.mesh else {
        return Err(Error::invalid(
            packing_path,
            "the sleeper is a cuboid; the track scene needs a sleeper mesh (sleepers.mesh in the bed scene)",
        ));
    };
    let packed = packing
        .meshes
        .iter()
        .map(|m| m.spheres_m)
        .fold(0.0, f64::max);
    let ours = scene.track.sphere_diameter.si();
    if packed > 0.0 && (packed != ours || scene.track.sphere_centres == SphereCentres::Inset) {
        println!(
            "ballast-qdem: note: the bed was packed with {:.1} mm spheres at the surface \
             nodes; this run puts {:.1} mm spheres {}, so it does not start at rest",
            packed * 1e3,
            ours * 1e3,
            match scene.track.sphere_centres {
                SphereCentres::Inset => "inset",
                _ => "at the nodes",
            }
        );
    }
    if packing.sides == "walls" && scene.track.periodic != Periodic::None {
        println!(
            "ballast-qdem: note: the bed was packed between walls and is read periodic \
             (track.periodic): the stones at its ends lose their walls and do not start \
             at rest"
        );
    }
    let mut meshes: HashMap<usize, TetMesh> = HashMap::new();
    let mut mesh = |k: usize| -> Result<TetMesh> {
        if let Some(m) = meshes.get(&k) {
            return Ok(m.clone());
        }
        let spec = packing.meshes.get(k).ok_or_else(|| {
            Error::invalid(packing_path, format!("mesh index {k} is not in [[mesh]]"))
        })?;
        // Packing::read resolved the file against the packing's directory. Nodes along a
        // Morton curve: in gmsh's order a tetra's four nodes lie half the sleeper's node
        // array apart (2 516 of 5 623 on average for the paper sleeper), so the blocks of
        // one colour, run on two threads, wrote forces into shared cache lines; the
        // tetra kernel took 1.78 × its 1-thread CPU time on 2 threads, 1.36 × in this
        // order, and the paper preset's 2-thread step 10 % less time (docs/track.md,
        // "Not done yet").
        let m = read_msh(&spec.file)?.locality_ordered();
        meshes.insert(k, m.clone());
        Ok(m)
    };
    let placed = |m: &TetMesh, k: usize, place: &crate::pack::Placement| -> Vec<Point3<f64>> {
        let pose = place.pose();
        let s = packing.meshes[k].scale;
        m.nodes
            .iter()
            .map(|p| pose * Point3::from(p.coords * s))
            .collect()
    };
    let sleeper_mesh = mesh(sleeper_mesh_index)?;
    sleeper_mesh
        .require_groups(&["rail_seat_1", "rail_seat_2"])
        .map_err(|e| Error::invalid(packing_path, e.to_string()))?;
    let sleeper_world = placed(&sleeper_mesh, sleeper_mesh_index, sleeper_place);
    let (sleeper_lo, sleeper_hi) = bounds(&sleeper_world);

    // Which stones deform.
    let t = &scene.track;
    let mut stone_nodes = Vec::with_capacity(packing.stones.len());
    let mut stone_meshes = Vec::with_capacity(packing.stones.len());
    for (i, place) in packing.stones.iter().enumerate() {
        let k = place
            .mesh
            .ok_or_else(|| Error::invalid(packing_path, format!("stone {i} has no mesh")))?;
        let m = mesh(k)?;
        stone_nodes.push(placed(&m, k, place));
        stone_meshes.push(m);
    }
    let deforms = |nodes: &[Point3<f64>]| -> bool {
        match t.stones {
            StoneModel::Rigid => false,
            StoneModel::Deformable => true,
            StoneModel::Near => {
                let c = centroid(nodes);
                let within = t.deformable_within.map_or(0.0, |l| l.si());
                let d2: f64 = (0..3)
                    .map(|d| {
                        (sleeper_lo[d] - c[d])
                            .max(c[d] - sleeper_hi[d])
                            .max(0.0)
                            .powi(2)
                    })
                    .sum();
                d2.sqrt() <= within
            }
        }
    };

    // The merged model: sleeper, then deformable stones.
    let mut nodes: Vec<Point3<f64>> = sleeper_world.clone();
    let mut tets: Vec<[u32; 4]> = sleeper_mesh.tets.clone();
    let mut tet_material = vec![0u32; tets.len()];
    let mut tet_body = vec![0u32; tets.len()];
    let mut bodies = vec![BodyKind::Deformable {
        nodes: 0..nodes.len() as u32,
    }];
    let radius = 0.5 * t.sphere_diameter.si();
    let inset = t.sphere_centres == SphereCentres::Inset;
    // (node, material, owner body, deformable index, (inset, radius)), ascending by node.
    let mut node_spheres: Vec<NodeSphere> = Vec::new();
    let mut rigid_radii: Vec<Vec<f64>> = Vec::new();
    let mut deformable: Vec<std::ops::Range<u32>> = Vec::new();
    deformable.push(0..sleeper_world.len() as u32);
    {
        let surface = sleeper_mesh.surface_nodes();
        let insets = sphere_insets(
            &sleeper_world,
            &sleeper_mesh.boundary,
            &surface,
            radius,
            inset,
        );
        let (surface, insets): (Vec<u32>, Vec<([f64; 3], f64)>) = surface
            .iter()
            .zip(insets)
            .filter(|(_, o)| o.1 > 0.0)
            .map(|(&n, o)| (n, o))
            .unzip();
        node_spheres.extend(
            surface
                .iter()
                .zip(insets)
                .map(|(&n, o)| (n, SLEEPER, 0, 0, o)),
        );
    }
    let mut rigid = Vec::new();
    let mut rigid_triangles = Vec::new();
    let mut rigid_vertices = Vec::new();
    let mut rigid_body_ids = Vec::new();
    let mut stone_body = Vec::with_capacity(packing.stones.len());
    let mut sizes = 0.0;
    let ballast_density = scene.ballast.material.density.si();
    for (i, (m, world)) in stone_meshes.iter().zip(&stone_nodes).enumerate() {
        let body = bodies.len() as u32;
        let surface = m.surface_nodes();
        let (surface, insets): (Vec<u32>, Vec<([f64; 3], f64)>) = surface
            .iter()
            .zip(sphere_insets(world, &m.boundary, &surface, radius, inset))
            .filter(|(_, o)| o.1 > 0.0)
            .map(|(&n, o)| (n, o))
            .unzip();
        sizes += equivalent_diameter(world, &m.tets);
        if deforms(world) {
            let offset = nodes.len() as u32;
            nodes.extend_from_slice(world);
            for tet in &m.tets {
                tets.push(tet.map(|n| n + offset));
                tet_material.push(1);
                tet_body.push(body);
            }
            let d = deformable.len() as u32;
            node_spheres.extend(
                surface
                    .iter()
                    .zip(insets)
                    .map(|(&n, o)| (n + offset, BALLAST, body, d, o)),
            );
            deformable.push(offset..nodes.len() as u32);
            bodies.push(BodyKind::Deformable {
                nodes: offset..nodes.len() as u32,
            });
            stone_body.push(SensorAt::DeformableStone(offset..nodes.len() as u32));
        } else {
            let centres: Vec<Point3<f64>> = surface
                .iter()
                .zip(&insets)
                .map(|(&n, o)| world[n as usize] + Vector3::from(o.0))
                .collect();
            rigid_radii.push(insets.iter().map(|o| o.1).collect());
            let shape = RigidShape::from_tets(world, &m.tets, ballast_density, &centres)
                .ok_or_else(|| {
                    Error::invalid(packing_path, format!("stone {i}: its mesh has no volume"))
                })?;
            let index = rigid.len() as u32;
            // The surface for VTK: every boundary vertex, in the principal frame.
            let all = m.surface_nodes();
            let local: HashMap<u32, u32> = all
                .iter()
                .enumerate()
                .map(|(k, &n)| (n, k as u32))
                .collect();
            rigid_triangles.push(
                m.boundary
                    .iter()
                    .map(|tri| tri.map(|n| local[&n]))
                    .collect(),
            );
            let c = Vector3::from(shape.centre);
            rigid_vertices.push(
                all.iter()
                    .map(|&n| {
                        let p = shape
                            .axes
                            .inverse_transform_vector(&(world[n as usize].coords - c));
                        [p.x, p.y, p.z]
                    })
                    .collect(),
            );
            rigid.push(shape);
            rigid_body_ids.push(body);
            bodies.push(BodyKind::Rigid { index });
            stone_body.push(SensorAt::RigidStone(index));
        }
    }
    let deformable_stones = bodies.len() - 1 - rigid.len();
    let materials = [
        qdem_material(&scene.sleeper.material),
        qdem_material(&scene.ballast.material),
    ];
    let model = QdemModel::with_materials(&nodes, &tets, &materials, &tet_material)
        .map_err(|e| Error::invalid(packing_path, e.to_string()))?;

    // Spheres: node spheres ascending, then each rigid body's.
    let mut spheres = Vec::new();
    let mut set = SphereSet {
        radius: Vec::new(),
        owner: Vec::new(),
        material: Vec::new(),
        mass: Vec::new(),
        planes: Vec::new(),
        laws: Vec::new(),
        materials: 4,
        period: None,
        shared_rest: t.rest_pairs == RestPairs::Shared,
    };
    for &(node, material, owner, body, (inset, r)) in &node_spheres {
        spheres.push(SphereAt::Node { node, body, inset });
        set.radius.push(r);
        set.owner.push(owner);
        set.material.push(material);
        set.mass.push(model.node_masses()[node as usize]);
    }
    let mut rigid_spheres = Vec::with_capacity(rigid.len());
    for (b, shape) in rigid.iter().enumerate() {
        let start = spheres.len();
        for (k, &r) in rigid_radii[b].iter().enumerate() {
            spheres.push(SphereAt::Rigid {
                body: b as u32,
                k: k as u32,
            });
            set.radius.push(r);
            set.owner.push(rigid_body_ids[b]);
            set.material.push(RIGID_BALLAST);
            set.mass.push(shape.mass);
        }
        rigid_spheres.push(start..spheres.len());
    }
    set.laws = laws(scene);
    let (lo, hi) = (packing.container_min, packing.container_max);
    set.planes.push(Plane {
        point: lo,
        normal: [0.0, 0.0, 1.0],
        material: BASE,
    });
    let periodic_axis = match t.periodic {
        Periodic::None => None,
        Periodic::X => Some(0),
        Periodic::Y => Some(1),
    };
    // Walls on the sides that are not periodic (a packing's sides are walls, or
    // periodic along x; the scene chooses how the track scene treats x).
    for axis in 0..2 {
        if Some(axis) == periodic_axis {
            continue;
        }
        let mut n = [0.0; 3];
        n[axis] = 1.0;
        set.planes.push(Plane {
            point: lo,
            normal: n,
            material: BASE,
        });
        n[axis] = -1.0;
        set.planes.push(Plane {
            point: hi,
            normal: n,
            material: BASE,
        });
    }
    if let Some(axis) = periodic_axis {
        set.period = Some(Period {
            axis,
            low: lo[axis],
            length: hi[axis] - lo[axis],
        });
    }

    // At each rail seat: its load, downwards, spread equally over the group's nodes;
    // and the rails' hold, along the track and along the sleeper, horizontal (the
    // sleeper mesh's x runs along the sleeper).
    let mut boundary = Boundary {
        gravity: Vector3::new(0.0, 0.0, -9.81),
        ..Boundary::default()
    };
    let axis = sleeper_place.pose().rotation * Vector3::x();
    let lateral = Vector3::new(axis.x, axis.y, 0.0)
        .try_normalize(1e-6)
        .ok_or_else(|| {
            Error::invalid(
                packing_path,
                "the sleeper stands on end (its axis is vertical): no track direction \
                 for the rails' hold",
            )
        })?;
    let longitudinal = Vector3::z().cross(&lateral);
    for (seat, group) in ["rail_seat_1", "rail_seat_2"].into_iter().enumerate() {
        let nodes = &sleeper_mesh.group(group).expect("checked above").nodes;
        if let Some(loads) = loads {
            let values = if seat == 0 { &loads.rp1 } else { &loads.rp2 };
            let (times, values) = shifted_table(&loads.times, values, t.settle.si());
            boundary.loads.push(NodalLoad {
                nodes: nodes.clone(),
                total_force: Vector3::new(0.0, 0.0, -1.0),
                time_fn: TimeFunction::Table { times, values },
            });
        }
        for (direction, k) in [
            (longitudinal, scene.rail.longitudinal.si()),
            (lateral, scene.rail.lateral.si()),
        ] {
            if k > 0.0 {
                boundary.springs.push(GroupSpring {
                    nodes: nodes.clone(),
                    direction,
                    stiffness: k,
                });
            }
        }
    }
    let sleeper_bottom = sleeper_mesh
        .group("bottom")
        .map(|g| g.nodes.clone())
        .unwrap_or_default();

    // Sensors.
    let pose = sleeper_place.pose();
    let s = packing.meshes[sleeper_mesh_index].scale;
    let mut sensors = Vec::new();
    for (i, spec) in scene.sensor.iter().enumerate() {
        let local = Point3::new(spec.at[0].si(), spec.at[1].si(), spec.at[2].si());
        let p = pose * Point3::from(local.coords * s);
        let at = match spec.on {
            SensorOn::Sleeper => {
                let n = (0..sleeper_world.len())
                    .min_by(|&a, &b| {
                        (sleeper_world[a] - p)
                            .norm()
                            .total_cmp(&(sleeper_world[b] - p).norm())
                    })
                    .expect("the sleeper has nodes");
                SensorAt::Node(n as u32)
            }
            SensorOn::Stone => {
                let k = (0..stone_nodes.len())
                    .min_by(|&a, &b| {
                        let da = (Point3::from(centroid(&stone_nodes[a])) - p).norm();
                        let db = (Point3::from(centroid(&stone_nodes[b])) - p).norm();
                        da.total_cmp(&db)
                    })
                    .ok_or_else(|| {
                        Error::invalid(
                            scene_path,
                            format!("sensor[{i}]: the packing has no stones"),
                        )
                    })?;
                stone_body[k].clone()
            }
        };
        sensors.push(Sensor {
            name: spec.name.clone(),
            at,
        });
    }
    let stone_count = packing.stones.len().max(1);
    Ok(Track {
        system: MultiBody {
            model: Some(model),
            boundary,
            rigid,
            bodies,
            spheres,
            rigid_spheres,
            deformable,
            insets: inset,
            set,
            gravity: [0.0, 0.0, -9.81],
        },
        sleeper_nodes: sleeper_world.len(),
        tets,
        tet_body,
        rigid_triangles,
        rigid_vertices,
        deformable_stones,
        sensors,
        sleeper_bottom,
        stone_size: sizes / stone_count as f64,
    })
}

/// The law table `laws[a * 4 + b]` over sleeper, ballast, rigid ballast, base.
fn laws(scene: &TrackScene) -> Vec<ContactLaw> {
    let springs = |s: &super::scene::Springs| SphereMaterial {
        normal_stiffness: s.normal.si(),
        tangential_stiffness: s.tangential.si(),
    };
    let mats = [
        springs(&scene.sleeper.springs),
        springs(&scene.ballast.springs),
        springs(&scene.ballast.springs),
        springs(&scene.base),
    ];
    let f = &scene.friction;
    let zeta = scene.track.rigid_damping_ratio;
    let mut out = Vec::with_capacity(16);
    for a in 0..4u16 {
        for b in 0..4u16 {
            let pair = |x: u16, y: u16| (a == x && b == y) || (a == y && b == x);
            let mu = if a == BASE || b == BASE {
                f.base
            } else if pair(SLEEPER, BALLAST) || pair(SLEEPER, RIGID_BALLAST) {
                f.ballast_sleeper
            } else {
                f.ballast_ballast
            };
            let damping = if a == RIGID_BALLAST || b == RIGID_BALLAST {
                zeta
            } else {
                0.0
            };
            out.push(ContactLaw::between(
                &mats[a as usize],
                &mats[b as usize],
                mu,
                damping,
            ));
        }
    }
    out
}

/// The load table shifted by the settling time, starting from 0 N at t = 0.
fn shifted_table(times: &[f64], values: &[f64], settle: f64) -> (Vec<f64>, Vec<f64>) {
    let mut t: Vec<f64> = Vec::with_capacity(times.len() + 1);
    let mut v = Vec::with_capacity(values.len() + 1);
    if settle + times[0] > 0.0 {
        t.push(0.0);
        v.push(0.0);
    }
    t.extend(times.iter().map(|x| x + settle));
    v.extend_from_slice(values);
    (t, v)
}

fn qdem_material(m: &crate::scene::Material) -> QdemMaterial {
    let (_, mu) = m.viscous_lame();
    QdemMaterial {
        density: m.density.si(),
        young_modulus: m.young_modulus.si(),
        poisson_ratio: m.poisson,
        shear_viscosity: mu,
        bulk_viscosity: m.bulk_viscosity.map_or(0.0, |v| v.si()),
    }
}

/// A vertex sphere's radius is at least this fraction of the longest surface edge at
/// the vertex, so neighbouring spheres overlap along every edge (2 × 0.6 > 1) and
/// cover the middle of every triangle (an equilateral one's circumradius is 0.577 e):
/// the sphere surface has no holes a sphere of another body could pass through. On
/// seed 004's meshes (10 mm edges, 24 mm spheres) the scene's diameter already does.
pub const COVER: f64 = 0.6;

/// With `inset` false: spheres of radius r centred on the vertices (seed 004; on a mesh
/// coarser than the spheres the sphere surface has holes, but the rest overlaps of the
/// packing's pairs hold the bed as it was packed).
/// With `inset`: sphere centres (as offsets from the surface nodes `surface`, ascending) and radii
/// (the scene's r, or [`COVER`] × the longest edge at the vertex if larger) for a body
/// with outward boundary triangles `boundary`, so that every sphere lies
/// inside the body: the centre goes in by d = r / max(min_f n̂·n_f, 1/3) along the
/// area-weighted vertex normal n̂ (n_f: the normals of the vertex's faces; d = r on a
/// flat face, where the sphere touches the face), halved until it is inside the body
/// (winding number), and the radius is r or the distance to the surface if that is
/// smaller (sharp edges, thin stones). The spheres' envelope is then the polyhedron
/// with rounded edges and corners, not the polyhedron dilated by r: a packing of the
/// polyhedra (ballast-pack) starts without the sphere overlaps that would blow it up.
/// Seed 004 centres its spheres on the vertices and packs with them.
fn sphere_insets(
    nodes: &[Point3<f64>],
    boundary: &[[u32; 3]],
    surface: &[u32],
    r: f64,
    inset: bool,
) -> Vec<([f64; 3], f64)> {
    use parry3d_f64::query::PointQuery;
    use parry3d_f64::shape::Triangle;
    let index: HashMap<u32, usize> = surface.iter().enumerate().map(|(k, &n)| (n, k)).collect();
    let mut normal = vec![Vector3::zeros(); surface.len()];
    let mut faces: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); surface.len()];
    let mut longest = vec![0.0f64; surface.len()];
    let triangles: Vec<[Point3<f64>; 3]> = boundary
        .iter()
        .map(|t| t.map(|n| nodes[n as usize]))
        .collect();
    for (tri, p) in boundary.iter().zip(&triangles) {
        let area_normal = (p[1] - p[0]).cross(&(p[2] - p[0]));
        let Some(unit) = area_normal.try_normalize(0.0) else {
            continue;
        };
        let edges = [
            (p[1] - p[0]).norm(),
            (p[2] - p[1]).norm(),
            (p[0] - p[2]).norm(),
        ];
        for (c, n) in tri.iter().enumerate() {
            let k = index[n];
            normal[k] += area_normal;
            faces[k].push(unit);
            longest[k] = longest[k].max(edges[c]).max(edges[(c + 2) % 3]);
        }
    }
    // Generalised winding number: Σ solid angles / 4π, 1 inside, 0 outside.
    let inside = |c: &Point3<f64>| -> bool {
        let mut omega = 0.0;
        for p in &triangles {
            let [a, b, d] = p.map(|q| q - c);
            let (la, lb, ld) = (a.norm(), b.norm(), d.norm());
            let num = a.dot(&b.cross(&d));
            let den = la * lb * ld + a.dot(&b) * ld + a.dot(&d) * lb + b.dot(&d) * la;
            omega += 2.0 * num.atan2(den);
        }
        omega > 2.0 * std::f64::consts::PI
    };
    let clearance = |c: &Point3<f64>| -> f64 {
        triangles
            .iter()
            .map(|p| Triangle::new(p[0], p[1], p[2]).distance_to_local_point(c, false))
            .fold(f64::INFINITY, f64::min)
    };
    surface
        .iter()
        .zip(normal.iter().zip(&faces))
        .zip(&longest)
        .map(|((&v, (n, fs)), &edge)| {
            if !inset {
                return ([0.0; 3], r);
            }
            let r = r.max(COVER * edge);
            let Some(n) = n.try_normalize(0.0) else {
                return ([0.0; 3], r);
            };
            let min_cos = fs.iter().map(|f| f.dot(&n)).fold(1.0f64, f64::min);
            let mut d = r / min_cos.max(1.0 / 3.0);
            let vertex = nodes[v as usize];
            for _ in 0..8 {
                let c = vertex - d * n;
                if inside(&c) {
                    return ([-d * n.x, -d * n.y, -d * n.z], r.min(clearance(&c)));
                }
                d *= 0.5;
            }
            ([0.0; 3], 0.0)
        })
        .collect()
}

/// Nodes on the mesh's boundary faces, ascending.
fn centroid(nodes: &[Point3<f64>]) -> [f64; 3] {
    let mut c = [0.0; 3];
    for p in nodes {
        for d in 0..3 {
            c[d] += p[d] / nodes.len() as f64;
        }
    }
    c
}

fn bounds(nodes: &[Point3<f64>]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in nodes {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

fn equivalent_diameter(nodes: &[Point3<f64>], tets: &[[u32; 4]]) -> f64 {
    let v: f64 = tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|i| nodes[i as usize].coords);
            (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
        })
        .sum();
    (6.0 * v / std::f64::consts::PI).cbrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::boundary_faces;
    use crate::qdem::structured_box;

    #[test]
    fn the_spheres_lie_inside_a_box_and_cover_its_surface() {
        let (nodes, tets) = structured_box(Vector3::new(0.4, 0.3, 0.2), [4, 3, 2]);
        let boundary = boundary_faces(&tets).unwrap();
        let mesh = TetMesh::from_parts("box", nodes.clone(), tets, Vec::new()).unwrap();
        assert_eq!(mesh.boundary.len(), boundary.len());
        let surface = mesh.surface_nodes();
        let insets = sphere_insets(&nodes, &mesh.boundary, &surface, 0.012, true);
        for (&n, (o, radius)) in surface.iter().zip(&insets) {
            let r = *radius;
            assert!(r >= 0.012 && r <= COVER * 0.1 * 2f64.sqrt() + 1e-12, "{r}");
            let c = nodes[n as usize].coords + Vector3::from(*o);
            // Inside every face plane by at least r (to round-off), touching at least one.
            let gaps = [c.x, 0.4 - c.x, c.y, 0.3 - c.y, c.z, 0.2 - c.z];
            // Inside the box, touching a face where the centre went in by r.
            let min = gaps.iter().fold(f64::INFINITY, |a, &b| a.min(b));
            assert!(min >= r - 1e-12, "node {n}: r {r}, {gaps:?}");
            if o.iter().map(|c| c * c).sum::<f64>().sqrt() < r * 1.000001 {
                assert!((min - r).abs() < 1e-12, "node {n}: r {r}, {gaps:?}");
            }
        }
    }
}

// One random convex ballast stone from an integer seed (seed 004 §4: ≈ 100 tetra).
//
// Method: a box L × (elong·L) × (flat·elong·L), centred at the origin, cut by `ncut`
// random planes. Each plane has a normal uniform on the sphere and keeps the part
// {x : n·x ≤ h(n)·(1 − depth·u)}, where h(n) is the box's support function (the
// distance from the centre to the farthest box corner along n) and u is uniform in
// [depth_min/depth, 1]: every cut takes a corner or an edge off, never the whole box.
// The intersection of a box with half-spaces is convex by construction. A cut that would
// leave a short edge, a thin face or nearly coplanar faces is undone and another drawn
// (see "plane cuts"): such features force slivers into a coarse tetra mesh.
//
// Random numbers come from our own Park–Miller generator (x ← 16807 x mod 2^31 − 1),
// written in the .geo arithmetic: every product stays below 2^53, so it is exact in
// doubles and the stone depends only on `seed` (gmsh's Rand() uses the C library's
// rand(), which General.RandomSeed does not seed, and which differs across platforms).
//
// Run: gmsh geo/stone.geo -3 -format msh41 -setnumber seed 7 -setnumber size 0.05 -o s.msh
SetFactory("OpenCASCADE");

DefineConstant[
  seed = {1, Name "Parameters/seed"},            // any integer ≥ 0
  size = {0.05, Name "Parameters/size"},         // box length L before cuts (m)
  elong = {0.645, Name "Parameters/elong"},       // box I/L
  flat = {0.62, Name "Parameters/flat"},         // box S/I
  ncut = {10, Name "Parameters/ncut"},           // number of plane cuts
  depth = {0.30, Name "Parameters/depth"},       // largest cut depth, fraction of h(n)
  depth_min = {0.05, Name "Parameters/depth_min"}, // smallest cut depth, fraction of h(n)
  angle_min = {25, Name "Parameters/angle_min"}, // smallest angle between face normals (deg)
  gap_min = {0.10, Name "Parameters/gap_min"},   // smallest vertex-edge distance / size
  tries = {60, Name "Parameters/tries"},         // most candidate cuts drawn
  mesh_factor = {0.55, Name "Parameters/mesh_factor"}, // element size / (bbox volume)^(1/3)
  verbose = {0, Name "Parameters/verbose"}       // 1: print the number of cuts accepted
];

// --- random numbers -------------------------------------------------------------
rng_m = 2147483647;
rng_state = 1 + Modulo(Fabs(Round(seed)) * 7919 + 12345, rng_m - 1);
Macro NextUniform
  // u in (0, 1); a few warm-up draws decorrelate nearby seeds.
  rng_state = Modulo(16807 * rng_state, rng_m);
  u = rng_state / rng_m;
Return
For k In {1:8}
  Call NextUniform;
EndFor

// --- the box --------------------------------------------------------------------
hx = size / 2;
hy = elong * size / 2;
hz = flat * elong * size / 2;
Box(1) = {-hx, -hy, -hz, 2 * hx, 2 * hy, 2 * hz};
stone = 1;

// --- plane cuts -----------------------------------------------------------------
// A candidate cut is drawn, then accepted only when it keeps the stone free of small
// features that force slivers into a coarse mesh:
//  * its normal makes at least `angle_min` degrees with every earlier face normal (the
//    box's six and the accepted cuts'): no nearly coplanar neighbour faces;
//  * on the cut stone, every vertex lies at least `gap_min`·size from every edge that
//    does not end at it (this bounds the edge lengths too, and rules out thin faces and
//    sharp face corners).
// Rejected candidates are undone; draws go on until `ncut` cuts are accepted or
// `tries` candidates were drawn.
big = 4 * size; // the half-space is a cube of side 2·big, far larger than the stone
gap = gap_min * size;
cos_max = Cos(angle_min * Pi / 180);
face_nx() = {1, -1, 0, 0, 0, 0};
face_ny() = {0, 0, 1, -1, 0, 0};
face_nz() = {0, 0, 0, 0, 1, -1};
accepted = 0;
drawn = 0;
For attempt In {1:tries}
If (accepted < ncut)
  drawn += 1;
  Call NextUniform; nz = 2 * u - 1;
  Call NextUniform; phi = 2 * Pi * u;
  rxy = Sqrt(1 - nz * nz);
  nx = rxy * Cos(phi);
  ny = rxy * Sin(phi);
  support = hx * Fabs(nx) + hy * Fabs(ny) + hz * Fabs(nz);
  Call NextUniform;
  cut_depth = depth_min + (depth - depth_min) * u;
  offset = support * (1 - cut_depth);
  ok = 1;
  For k In {0:#face_nx() - 1}
    If (nx * face_nx(k) + ny * face_ny(k) + nz * face_nz(k) > cos_max)
      ok = 0;
    EndIf
  EndFor
  If (ok)
    // Half-space box: z' ∈ [offset − 2 big, offset] along n, wide in the other two
    // axes; built along z, then rotated so that z goes to n (axis z × n, angle acos nz).
    half = newv;
    Box(half) = {-big, -big, offset - 2 * big, 2 * big, 2 * big, 2 * big};
    axis_x = -ny;
    axis_y = nx;
    If (rxy > 1e-9)
      Rotate {{axis_x, axis_y, 0}, {0, 0, 0}, Atan2(rxy, nz)} { Volume{half}; }
    ElseIf (nz < 0)
      Rotate {{1, 0, 0}, {0, 0, 0}, Pi} { Volume{half}; }
    EndIf
    result() = BooleanIntersection{ Volume{stone}; }{ Volume{half}; Delete; };
    candidate = result(0);
    If (candidate == stone)
      ok = 0; // the plane misses the stone: OpenCASCADE hands back the same volume
    EndIf
    // Smallest vertex–edge distance of the candidate (edges not ending at the vertex).
    vertices() = PointsOf{ Volume{candidate}; };
    edges() = Unique(Abs(Boundary{ Surface{ Boundary{ Volume{candidate}; } }; }));
    For e In {0:(#edges() - 1) * ok} // one pass only when the candidate is already out
      ends() = PointsOf{ Curve{edges(e)}; };
      pa() = Point{ends(0)};
      pb() = Point{ends(1)};
      ex = pb(0) - pa(0); ey = pb(1) - pa(1); ez = pb(2) - pa(2);
      elen2 = ex * ex + ey * ey + ez * ez;
      If (elen2 < gap * gap)
        ok = 0;
      EndIf
      For v In {0:#vertices() - 1}
        If (ok && vertices(v) != ends(0) && vertices(v) != ends(1))
          pv() = Point{vertices(v)};
          t = ((pv(0) - pa(0)) * ex + (pv(1) - pa(1)) * ey + (pv(2) - pa(2)) * ez) / elen2;
          t = Min(1, Max(0, t));
          dx = pv(0) - pa(0) - t * ex; dy = pv(1) - pa(1) - t * ey; dz = pv(2) - pa(2) - t * ez;
          If (dx * dx + dy * dy + dz * dz < gap * gap)
            ok = 0;
          EndIf
        EndIf
      EndFor
    EndFor
    If (ok)
      Recursive Delete { Volume{stone}; }
      stone = candidate;
      accepted += 1;
      face_nx() += nx;
      face_ny() += ny;
      face_nz() += nz;
    ElseIf (candidate != stone)
      Recursive Delete { Volume{candidate}; }
    EndIf
  EndIf
EndIf
EndFor
If (verbose)
  Printf("stone seed %g: %g cuts accepted of %g drawn", seed, accepted, drawn);
EndIf

// --- mesh -----------------------------------------------------------------------
bb() = BoundingBox Volume{stone};
bbox_volume = (bb(3) - bb(0)) * (bb(4) - bb(1)) * (bb(5) - bb(2));
lc = mesh_factor * bbox_volume^(1 / 3);
MeshSize{ PointsOf{ Volume{stone}; } } = lc;
Mesh.MeshSizeMax = lc;
Mesh.MeshSizeFromCurvature = 0;
// 0: short CAD edges do not shrink the elements inside their faces (fewer, better tetra).
Mesh.MeshSizeExtendFromBoundary = 0;
// HXT (10) makes far fewer slivers than Delaunay (1) on these few-node meshes (family
// min quality 0.17 against 0.04 on the same geometry; docs/stones.md).
Mesh.Algorithm3D = 10;
Mesh.Optimize = 1;

Physical Volume("stone") = {stone};
Physical Surface("surface") = Boundary{ Volume{stone}; };

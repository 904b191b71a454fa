// One random convex ballast stone from an integer seed (seed 004 §4: ≈ 100 tetra).
//
// Method: a box L × (elong·L) × (flat·elong·L), centred at the origin, cut by `ncut`
// random planes. Each plane has a normal uniform on the sphere and keeps the part
// {x : n·x ≤ h(n)·(1 − depth·u)}, where h(n) is the box's support function (the
// distance from the centre to the farthest box corner along n) and u is uniform in
// [depth_min/depth, 1]: every cut takes a corner or an edge off, never the whole box.
// The intersection of a box with half-spaces is convex by construction.
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
  mesh_factor = {0.8, Name "Parameters/mesh_factor"} // element size / (bbox volume)^(1/3)
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
big = 4 * size; // the half-space is a cube of side 2·big, far larger than the stone
For c In {1:ncut}
  Call NextUniform; nz = 2 * u - 1;
  Call NextUniform; phi = 2 * Pi * u;
  rxy = Sqrt(1 - nz * nz);
  nx = rxy * Cos(phi);
  ny = rxy * Sin(phi);
  support = hx * Fabs(nx) + hy * Fabs(ny) + hz * Fabs(nz);
  Call NextUniform;
  cut_depth = depth_min + (depth - depth_min) * u;
  offset = support * (1 - cut_depth);
  // Half-space box: z' ∈ [offset − 2 big, offset] along n, wide in the other two axes;
  // built along z, then rotated so that z goes to n (axis z × n, angle acos(nz)).
  half = newv;
  Box(half) = {-big, -big, offset - 2 * big, 2 * big, 2 * big, 2 * big};
  axis_x = -ny;
  axis_y = nx;
  If (rxy > 1e-9)
    Rotate {{axis_x, axis_y, 0}, {0, 0, 0}, Atan2(rxy, nz)} { Volume{half}; }
  ElseIf (nz < 0)
    Rotate {{1, 0, 0}, {0, 0, 0}, Pi} { Volume{half}; }
  EndIf
  result() = BooleanIntersection{ Volume{stone}; Delete; }{ Volume{half}; Delete; };
  stone = result(0);
EndFor

// --- mesh -----------------------------------------------------------------------
bb() = BoundingBox Volume{stone};
bbox_volume = (bb(3) - bb(0)) * (bb(4) - bb(1)) * (bb(5) - bb(2));
lc = mesh_factor * bbox_volume^(1 / 3);
MeshSize{ PointsOf{ Volume{stone}; } } = lc;
Mesh.MeshSizeMax = lc;
Mesh.MeshSizeFromCurvature = 0;
Mesh.MeshSizeExtendFromBoundary = 1;
Mesh.Algorithm3D = 1;
Mesh.Optimize = 1;

Physical Volume("stone") = {stone};
Physical Surface("surface") = Boundary{ Volume{stone}; };

// cantilever.geo — concrete cantilever beam of seed 004 (Nishiura et al. 2017,
// Materials 10, 615), §3.1 "Elastic Body" and §3.2 "Viscoelastic Body".
//
//   x: length 0 .. 2.4 m   (fixed end x = 0, free end / tip x = 2.4)
//   y: width  0 .. 0.25 m
//   z: height 0 .. 0.22 m  (z up; the tip load is -z)
//
// Material (not used by gmsh, recorded in docs/geometry.md): E = 45 GPa,
// nu = 0.167, rho = 2350 kg/m^3 (seed 004 §3.1).
//
// Mesh: linear tetrahedra of target edge length h.  The paper's mesh had
// 94 149 nodes / 488 361 tetra, reached here with h ≈ 0.0105 m
// (make: `-setnumber h 0.0105`).  The default h = 0.05 m is coarse and fast.
//
// Physical groups:
//   Volume  "beam"
//   Surface "fixed" (x = 0), "tip" (x = 2.4), "front" (y = 0), "back" (y = 0.25),
//           "bottom" (z = 0), "top" (z = 0.22)
//   Point   "tip_centre" (2.4, 0.125, 0.11)  — node where the paper reads the deflection
//           "top_centre" (1.2, 0.125, 0.22)  — node for the creep test strain (§3.2)

SetFactory("OpenCASCADE");

DefineConstant[
  h  = {0.05,  Name "Parameters/h",  Help "target tetra edge length [m]"},
  Lx = {2.4,   Name "Parameters/Lx", Help "length along x [m] (seed 004 §3.1)"},
  Ly = {0.25,  Name "Parameters/Ly", Help "width along y [m] (seed 004 §3.1)"},
  Lz = {0.22,  Name "Parameters/Lz", Help "height along z [m] (seed 004 §3.1)"}
];

beam = newv;
Box(beam) = {0, 0, 0, Lx, Ly, Lz};   // [m]

// Faces of the box, found by position (robust against OCC numbering).
eps = 1e-6;  // [m] bounding-box tolerance
s_fixed[]  = Surface In BoundingBox{-eps,   -eps,   -eps,   eps,     Ly+eps, Lz+eps};
s_tip[]    = Surface In BoundingBox{Lx-eps, -eps,   -eps,   Lx+eps,  Ly+eps, Lz+eps};
s_front[]  = Surface In BoundingBox{-eps,   -eps,   -eps,   Lx+eps,  eps,    Lz+eps};
s_back[]   = Surface In BoundingBox{-eps,   Ly-eps, -eps,   Lx+eps,  Ly+eps, Lz+eps};
s_bottom[] = Surface In BoundingBox{-eps,   -eps,   -eps,   Lx+eps,  Ly+eps, eps};
s_top[]    = Surface In BoundingBox{-eps,   -eps,   Lz-eps, Lx+eps,  Ly+eps, Lz+eps};

// Measurement points, embedded so that they are mesh nodes.
p_tip = newp;
Point(p_tip) = {Lx, Ly/2, Lz/2, h};      // tip-face centre [m]
p_top = newp;
Point(p_top) = {Lx/2, Ly/2, Lz, h};      // top-face centre [m]
Point{p_tip} In Surface{s_tip[0]};
Point{p_top} In Surface{s_top[0]};

// Uniform target size h everywhere.
MeshSize{ PointsOf{ Volume{beam}; } } = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;

Physical Volume("beam")   = {beam};
Physical Surface("fixed")  = {s_fixed[]};
Physical Surface("tip")    = {s_tip[]};
Physical Surface("front")  = {s_front[]};
Physical Surface("back")   = {s_back[]};
Physical Surface("bottom") = {s_bottom[]};
Physical Surface("top")    = {s_top[]};
Physical Point("tip_centre") = {p_tip};
Physical Point("top_centre") = {p_top};

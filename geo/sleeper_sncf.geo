// sleeper_sncf.geo — one concrete block ("blochet") of an SNCF twin-block
// ("bibloc") sleeper, for the 7-sleeper tamping slice of seed 000 (Hoang et al.,
// 3.6 m x 2 m x 0.56 m, sleepers at 0.60 m spacing; SNCF standard spacing is
// 1666 sleepers/km = 0.60 m).  In the NSCD model it is a rigid body, so the mesh
// only needs to describe its (convex) shape: the default mesh is coarse.
//
// SOURCED: block 0.67 m x 0.29 m x 0.21 m (length across the track x width along
//   the track x height), twin-block sleeper "Stram" (Stradal) laid on SNCF lines:
//   French heritage inventory record IM39002217 (Poupard 2004/2008),
//   https://pop.culture.gouv.fr/notice/palissy/IM39002217 — it also describes the
//   blocks as "sand-pile shaped" (tapered) with rounded top and vertical edges.
// NOT FOUND: the dimensions of the larger U41 (VAX U41) block; set L/W/H with
//   -setnumber when a sourced value is available.
// ASSUMED: the taper — the top face is inset by `taper` on every side (default
//   0.02 m); rounded edges and the lowered rail-seat table are not modelled.
//   taper = 0 gives a plain box.
//
// Frame (same as the tamping scene): x along the track (the tines squeeze along x
// against the x-faces), y across the track (block length), z up; the block is
// centred on x = y = 0 with its bottom at z = 0.
//
// Physical groups:  Volume "block";  Surface "bottom" (z = 0), "top" (z = H),
//                   "sides" (the four lateral faces).

SetFactory("OpenCASCADE");

DefineConstant[
  h     = {0.1,  Name "Parameters/h",     Help "target tetra edge length [m]"},
  L     = {0.67, Name "Parameters/L",     Help "block length across the track, along y [m] (IM39002217)"},
  W     = {0.29, Name "Parameters/W",     Help "block width along the track, along x [m] (IM39002217)"},
  H     = {0.21, Name "Parameters/H",     Help "block height [m] (IM39002217)"},
  taper = {0.02, Name "Parameters/taper", Help "horizontal inset of the top face on each side [m] (ASSUMED)"}
];

// Frustum: bottom rectangle W x L at z = 0, top rectangle (W-2t) x (L-2t) at z = H.
pb1 = newp; Point(pb1) = {-W/2, -L/2, 0};
pb2 = newp; Point(pb2) = { W/2, -L/2, 0};
pb3 = newp; Point(pb3) = { W/2,  L/2, 0};
pb4 = newp; Point(pb4) = {-W/2,  L/2, 0};
pt1 = newp; Point(pt1) = {-W/2+taper, -L/2+taper, H};
pt2 = newp; Point(pt2) = { W/2-taper, -L/2+taper, H};
pt3 = newp; Point(pt3) = { W/2-taper,  L/2-taper, H};
pt4 = newp; Point(pt4) = {-W/2+taper,  L/2-taper, H};
b1 = newl; Line(b1) = {pb1, pb2};
b2 = newl; Line(b2) = {pb2, pb3};
b3 = newl; Line(b3) = {pb3, pb4};
b4 = newl; Line(b4) = {pb4, pb1};
t1 = newl; Line(t1) = {pt1, pt2};
t2 = newl; Line(t2) = {pt2, pt3};
t3 = newl; Line(t3) = {pt3, pt4};
t4 = newl; Line(t4) = {pt4, pt1};
wb = newcl; Curve Loop(wb) = {b1, b2, b3, b4};
wt = newcl; Curve Loop(wt) = {t1, t2, t3, t4};
block = newv;
ThruSections(block) = {wb, wt};   // ruled frustum between the two rectangles

eps = 1e-6;  // [m] bounding-box tolerance
s_bottom[] = Surface In BoundingBox{-W/2-eps, -L/2-eps, -eps,  W/2+eps, L/2+eps, eps};
s_top[]    = Surface In BoundingBox{-W/2-eps, -L/2-eps, H-eps, W/2+eps, L/2+eps, H+eps};
s_sides[]  = Abs(Boundary{ Volume{block}; });
s_sides[] -= {s_bottom[], s_top[]};

MeshSize{ PointsOf{ Volume{block}; } } = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;

Physical Volume("block")   = {block};
Physical Surface("bottom") = {s_bottom[]};
Physical Surface("top")    = {s_top[]};
Physical Surface("sides")  = {s_sides[]};

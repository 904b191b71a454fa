// sleeper_type3.geo — JR Type-3 ("3号") prestressed-concrete monoblock sleeper,
// the sleeper of seed 004 (Nishiura et al. 2017, Materials 10, 615, §4 and Table 1).
//
// SOURCED (seed 004 §4): maximal length 2.0 m, maximal width 0.24 m, maximal
//   height 0.174 m; concrete E = 45 GPa, nu = 0.167, rho = 2350 kg/m^3 (Table 1).
// SOURCED (track): JR conventional-line gauge 1067 mm (between the inner faces of
//   the rail heads); 50N rail (JIS E 1101): head width 65 mm, foot width 127 mm.
// ASSUMED (profile not found in public sources; see docs/geometry.md):
//   - constant trapezoidal cross-section along the whole length (no thinner centre
//     section, no rail-seat cant, no shoulders or fastening inserts);
//   - the 0.24 m maximal width is the bottom width; the top width is 0.19 m.
//
// Frame: x along the sleeper (-L/2 .. L/2, i.e. across the track), y along the
// track (-W/2 .. W/2 at the bottom), z up (bottom z = 0, top z = H).
//
// Physical groups:
//   Volume  "sleeper"
//   Surface "rail_seat_1" (x < 0), "rail_seat_2" (x > 0): the rail-foot footprint on
//           the top face, centred at x = -/+ rail_centres/2, width = rail foot width
//           along x, full top width along y (where seed 004 applies its Rp1/Rp2 loads);
//           "top" (rest of the top face), "bottom", "sides" (the two inclined long
//           faces), "ends" (the faces at x = -/+ L/2).

SetFactory("OpenCASCADE");

DefineConstant[
  h     = {0.05,  Name "Parameters/h",     Help "target tetra edge length [m]"},
  L     = {2.0,   Name "Parameters/L",     Help "length [m] (seed 004 §4)"},
  W     = {0.24,  Name "Parameters/W",     Help "bottom (maximal) width [m] (seed 004 §4)"},
  Wtop  = {0.19,  Name "Parameters/Wtop",  Help "top width [m] (ASSUMED)"},
  H     = {0.174, Name "Parameters/H",     Help "height [m] (seed 004 §4)"},
  gauge = {1.067, Name "Parameters/gauge", Help "track gauge, inner faces of rail heads [m] (JR narrow gauge)"},
  head  = {0.065, Name "Parameters/head",  Help "rail head width [m] (JIS 50N rail)"},
  foot  = {0.127, Name "Parameters/foot",  Help "rail foot width = rail-seat length along x [m] (JIS 50N rail)"}
];

rail_centres = gauge + head;   // [m] distance between rail centre lines = 1.132 m
xs = rail_centres / 2;         // [m] rail-seat centre |x| = 0.566 m

// Trapezoidal cross-section in the plane x = -L/2, extruded along +x.
p1 = newp; Point(p1) = {-L/2, -W/2,    0};
p2 = newp; Point(p2) = {-L/2,  W/2,    0};
p3 = newp; Point(p3) = {-L/2,  Wtop/2, H};
p4 = newp; Point(p4) = {-L/2, -Wtop/2, H};
l1 = newl; Line(l1) = {p1, p2};
l2 = newl; Line(l2) = {p2, p3};
l3 = newl; Line(l3) = {p3, p4};
l4 = newl; Line(l4) = {p4, p1};
cl = newll; Curve Loop(cl) = {l1, l2, l3, l4};
sec = news; Plane Surface(sec) = {cl};
ex[] = Extrude {L, 0, 0} { Surface{sec}; };
body = ex[1];

// Rail-seat patches on the top face; fragmenting imprints them into the top face.
seat1 = news; Rectangle(seat1) = {-xs - foot/2, -Wtop/2, H, foot, Wtop};
seat2 = news; Rectangle(seat2) = { xs - foot/2, -Wtop/2, H, foot, Wtop};
BooleanFragments{ Volume{body}; Delete; }{ Surface{seat1, seat2}; Delete; }

eps = 1e-6;  // [m] bounding-box tolerance
vols[]   = Volume In BoundingBox{-L/2-eps, -W/2-eps, -eps, L/2+eps, W/2+eps, H+eps};
s_top_all[] = Surface In BoundingBox{-L/2-eps, -W/2-eps, H-eps, L/2+eps, W/2+eps, H+eps};
s_seat1[] = Surface In BoundingBox{-xs-foot/2-eps, -W/2-eps, H-eps, -xs+foot/2+eps, W/2+eps, H+eps};
s_seat2[] = Surface In BoundingBox{ xs-foot/2-eps, -W/2-eps, H-eps,  xs+foot/2+eps, W/2+eps, H+eps};
s_top[]   = s_top_all[];
s_top[]  -= {s_seat1[], s_seat2[]};
s_bottom[] = Surface In BoundingBox{-L/2-eps, -W/2-eps, -eps, L/2+eps, W/2+eps, eps};
s_end1[] = Surface In BoundingBox{-L/2-eps, -W/2-eps, -eps, -L/2+eps, W/2+eps, H+eps};
s_end2[] = Surface In BoundingBox{ L/2-eps, -W/2-eps, -eps,  L/2+eps, W/2+eps, H+eps};
s_all[] = Abs(Boundary{ Volume{vols[]}; });
s_sides[] = s_all[];
s_sides[] -= {s_top_all[], s_bottom[], s_end1[], s_end2[]};

MeshSize{ PointsOf{ Volume{vols[]}; } } = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;

Physical Volume("sleeper")      = {vols[]};
Physical Surface("rail_seat_1") = {s_seat1[]};
Physical Surface("rail_seat_2") = {s_seat2[]};
Physical Surface("top")         = {s_top[]};
Physical Surface("bottom")      = {s_bottom[]};
Physical Surface("sides")       = {s_sides[]};
Physical Surface("ends")        = {s_end1[], s_end2[]};

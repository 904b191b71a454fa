// tine.geo — a tamping tine: a straight shank ending in a flat paddle (blade).
// Used as a driven (kinematic) rigid body in the NSCD tamping scene of seed 000.
//
// Frame: z up; the tine tip (underside of the paddle) at z = 0, pointing down;
// the paddle is a plate whose broad faces are normal to x, so squeezing along x
// pushes ballast with the broad faces; y is the paddle width; centred on x = y = 0.
//
// SOURCED (order of magnitude only): a tine structure of width 60–70 mm and
//   height 75–80 mm is reported as optimal in a DEM study of a new tamping tine
//   (SAGE, doi:10.1177/10567895261460588, abstract) — the paddle below is
//   0.065 m wide and 0.08 m high, inside those ranges.  Plasser & Theurer describe
//   their tine as a one-piece forged "Monobloc" with a tungsten-carbide-armoured
//   tine plate whose underside is slanted 5° (plasser.com.au, "The tamping tine";
//   Railway Gazette 38491) — the slant is NOT modelled here.
// ASSUMED: paddle thickness 0.02 m; shank a straight cylinder of diameter 0.04 m
//   and length 0.40 m standing on the paddle (total 0.48 m, enough to reach
//   ~0.45 m into the ballast); no bend, no taper, no neck fillet.
// bc > 0 gives the paddle a chisel tip (an experiment, off by default): on the quick
//   tamping bed it did not remove the stone that stays 20+ mm into the blade
//   (docs/tamping.md, "Where the deep pairs come from").
//
// Physical groups:  Volume "tine";  Surface "blade" (all paddle faces),
//                   "shank" (the faces of the shank, z >= bh, incl. the overhanging
//                   underside of its bottom disc).

SetFactory("OpenCASCADE");

DefineConstant[
  h  = {0.012, Name "Parameters/h",  Help "target tetra edge length [m]"},
  bw = {0.065, Name "Parameters/bw", Help "paddle width along y [m] (SAGE 2026 range 60-70 mm)"},
  bh = {0.08,  Name "Parameters/bh", Help "paddle height along z [m] (SAGE 2026 range 75-80 mm)"},
  bt = {0.02,  Name "Parameters/bt", Help "paddle thickness along x [m] (ASSUMED)"},
  sd = {0.04,  Name "Parameters/sd", Help "shank diameter [m] (ASSUMED)"},
  sl = {0.40,  Name "Parameters/sl", Help "shank length above the paddle [m] (ASSUMED)"},
  bc = {0.0,   Name "Parameters/bc", Help "height of a chisel tip: the paddle's broad faces meet the tip edge at z = 0 over bc [m] (0: flat underside)"},
  be = {0.004, Name "Parameters/be", Help "thickness of the chisel's tip edge along x [m] (used when bc > 0)"}
];

paddle = 1;
If (bc > 0)
  // The paddle's cross-section in x-z, extruded along y: flat faces above z = bc,
  // tapering to a tip edge be thick at z = 0.
  pp[] = {};
  pp[] += newp; Point(pp[0]) = {-be/2, -bw/2, 0};
  pp[] += newp; Point(pp[1]) = { be/2, -bw/2, 0};
  pp[] += newp; Point(pp[2]) = { bt/2, -bw/2, bc};
  pp[] += newp; Point(pp[3]) = { bt/2, -bw/2, bh};
  pp[] += newp; Point(pp[4]) = {-bt/2, -bw/2, bh};
  pp[] += newp; Point(pp[5]) = {-bt/2, -bw/2, bc};
  ll[] = {};
  For i In {0:5}
    ll[] += newl; Line(ll[i]) = {pp[i], pp[(i+1)%6]};
  EndFor
  cl = newcl; Curve Loop(cl) = {ll[]};
  sf = news; Plane Surface(sf) = {cl};
  ex[] = Extrude{0, bw, 0}{ Surface{sf}; };
  paddle = ex[1];
Else
  Box(paddle) = {-bt/2, -bw/2, 0, bt, bw, bh};          // [m]
EndIf
shank = 2;
Cylinder(shank) = {0, 0, bh, 0, 0, sl, sd/2};          // [m] sits on the paddle's top face
// The shank (diameter sd) is thicker along x than the paddle (bt): its bottom disc
// overhangs the paddle on both x sides, as on real tines where a thin plate is
// carried by a thicker shank.
tine[] = BooleanUnion{ Volume{paddle}; Delete; }{ Volume{shank}; Delete; };

eps = 1e-6;  // [m] bounding-box tolerance
s_all[]   = Abs(Boundary{ Volume{tine[]}; });
s_blade[] = Surface In BoundingBox{-bt/2-eps, -bw/2-eps, -eps, bt/2+eps, bw/2+eps, bh+eps};
s_shank[] = s_all[];
s_shank[] -= {s_blade[]};

MeshSize{ PointsOf{ Volume{tine[]}; } } = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;

Physical Volume("tine")   = {tine[]};
Physical Surface("blade") = {s_blade[]};
Physical Surface("shank") = {s_shank[]};

// POV-Ray 3.7 version of sphere_minus_cube.xml, rendered as a mask (object white,
// background black) for crates/lightpath/tests/csg.rs. Reproduce with
//
//   povray +Isphere_minus_cube.pov +Osphere_minus_cube_mask.png +W320 +H240 -A +FN -D -V
//
// (POV-Ray 3.7.0.10, Debian package povray 3.7.0.10-2+b2; -A: one ray through each
// pixel centre, no antialiasing.)
//
// Conventions: lightpath's camera at the identity looks along +z with image right = +x
// and image DOWN = +y (right-handed); POV-Ray's looks along +z with right = +x and
// UP = +y (left-handed). So the scene is written in lightpath's coordinates and then
// mirrored by scale <1, -1, 1>, which maps every point to where POV-Ray's camera shows
// it at the same pixel. The instance transform (rotate y 25 deg, then x -20 deg, then
// translate z 4; right-handed rotations) is written as a matrix: POV-Ray's `matrix`
// multiplies row vectors, so its rows are the columns of lightpath's rotation, then the
// translation. Field of view: 40 deg horizontal; with right = 320/240 and up = 1 the
// direction length is (4/3) / (2 tan 20 deg) = 1.831651613.

#version 3.7;
global_settings { assumed_gamma 1.0 }
background { rgb 0 }

camera {
    perspective
    location <0, 0, 0>
    direction <0, 0, 1.831651613>
    right <320/240, 0, 0>
    up <0, 1, 0>
}

difference {
    sphere { <0, 0, 0>, 1 }
    box { <-1, -1, -1>, <1, 1, 1> scale 0.6 translate <0.7, -0.7, -0.3> }
    matrix <0.906307787, -0.144543958, -0.397131262,
            0.000000000,  0.939692621, -0.342020143,
            0.422618262,  0.309975519,  0.851650740,
            0, 0, 4>
    scale <1, -1, 1>
    pigment { rgb 1 }
    finish { ambient 0 diffuse 0 emission 1 }
}

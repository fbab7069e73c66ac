//! Stage 3, 3D frames (thesis chapter 4): SU(2) parameterization of frames by
//! octahedral invariant forms, volume tetrahedralization, frame field.

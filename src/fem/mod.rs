//! Element operators shared by the stages: P1 (linear Lagrange) and
//! Crouzeix–Raviart (edge-midpoint) shape functions on triangles, P1 on
//! tetrahedra, their stiffness and mass matrices.

pub mod crouzeix_raviart;
pub mod tet_p1;

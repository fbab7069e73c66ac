//! Stage 2, the crossfield (thesis chapter 3): Ginzburg–Landau crossfield on
//! Crouzeix–Raviart unknowns, its singularities and their indices.

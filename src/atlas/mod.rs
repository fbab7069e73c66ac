//! Stage 1, the atlas (thesis chapter 2): feature edges and curves, disk-like
//! patches, one-to-one mean value parameterization of each patch.

pub mod features;

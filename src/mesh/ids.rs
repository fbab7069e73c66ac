//! Typed 32-bit ids for vertices, edges, triangles and tetrahedra.
//!
//! Ids are `u32` (meshes above 4 billion elements are rejected at load) and
//! `#[repr(transparent)]`, so a `Vec<[VertexId; 3]>` has the layout of
//! `Vec<[u32; 3]>`.

use serde::{Deserialize, Serialize};

macro_rules! typed_id {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        #[repr(transparent)]
        #[serde(transparent)]
        pub struct $name(pub u32);

        impl $name {
            /// The id of the element at `index`.
            ///
            /// # Panics
            /// When `index` does not fit in 32 bits (callers check sizes at load).
            #[inline]
            pub fn new(index: usize) -> Self {
                Self(u32::try_from(index).expect("element index exceeds u32"))
            }

            /// This id as a `usize` index into per-element containers.
            #[inline]
            pub fn idx(self) -> usize {
                self.0 as usize
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{}", self.0)
            }
        }
    };
}

typed_id!(
    /// A vertex of a [`crate::mesh::TriMesh`] or [`crate::mesh::TetMesh`].
    VertexId
);
typed_id!(
    /// A triangle of a [`crate::mesh::TriMesh`].
    FaceId
);
typed_id!(
    /// An undirected edge of a [`crate::mesh::Topology`].
    EdgeId
);
typed_id!(
    /// A tetrahedron of a [`crate::mesh::TetMesh`].
    TetId
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_round_trip_and_have_u32_layout() {
        assert_eq!(VertexId::new(7).idx(), 7);
        assert_eq!(std::mem::size_of::<[VertexId; 3]>(), 12);
        assert_eq!(serde_json::to_string(&FaceId(3)).unwrap(), "3");
        assert_eq!(EdgeId(4).to_string(), "4");
    }
}

//! Surface texture synthesis in a texture atlas (Lefebvre & Hoppe 2006, section 6): mesh in, atlas,
//! tangent field, per-level Jacobian and indirection maps on the host, anisometric
//! synthesis in the atlas on the GPU, textured glTF out.

pub mod atlas;
pub mod flow;
#[cfg(feature = "gltf")]
pub mod gltf_io;
pub mod maps;
pub mod mesh;
pub mod pipeline;
pub mod render;
pub mod seams;
pub mod tangent_field;

#[cfg(all(feature = "xatlas", not(target_env = "msvc")))]
mod xatlas_link;

pub use mesh::Mesh;

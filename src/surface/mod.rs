//! Surface texture synthesis in a texture atlas (paper section 6): mesh in, atlas,
//! tangent field, per-level Jacobian and indirection maps on the host, anisometric
//! synthesis in the atlas on the GPU, textured glTF out.

pub mod mesh;

pub use mesh::Mesh;

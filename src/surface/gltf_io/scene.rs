//! The scene graph: which primitives are instanced (default scene, root nodes, node
//! hierarchy) with which world transform, and the merge of all of them into one mesh.

use glam::{Mat4, Vec2, Vec3, Vec4};
use gltf::mesh::Mode;

use super::primitive::read_primitive;
use super::LoadReport;
use crate::surface::mesh::Mesh;

/// One primitive, in world space.
pub(super) struct Part {
    pub(super) positions: Vec<Vec3>,
    pub(super) normals: Option<Vec<Vec3>>,
    pub(super) uvs: Option<Vec<Vec2>>,
    pub(super) tangents: Option<Vec<Vec4>>,
    pub(super) triangles: Vec<[u32; 3]>,
}

/// Instantiates the scene's primitives and merges them.
pub(super) fn assemble(
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
) -> std::result::Result<(Mesh, LoadReport), String> {
    let parent = node_parents(doc)?;
    let roots: Vec<gltf::Node> = match doc.default_scene() {
        Some(scene) => scene.nodes().collect(),
        None if doc.scenes().len() > 0 => doc.scenes().flat_map(|s| s.nodes()).collect(),
        None => doc
            .nodes()
            .filter(|n| parent[n.index()].is_none())
            .collect(),
    };

    let mut report = LoadReport::default();
    let mut parts = Vec::new();
    let mut visited = vec![false; parent.len()];
    let mut stack: Vec<(gltf::Node, Mat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY))
        .collect();
    while let Some((node, parent_world)) = stack.pop() {
        // A node listed twice (in two scenes, or as a root and as a descendant) is
        // instantiated once.
        if std::mem::replace(&mut visited[node.index()], true) {
            continue;
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        if !local.is_finite() {
            return Err(format!(
                "node {} has a transform with NaN or infinite values",
                node.index()
            ));
        }
        let world = parent_world * local;
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                let what = match mesh.name() {
                    Some(name) => format!(
                        "mesh {} ('{name}') primitive {}",
                        mesh.index(),
                        prim.index()
                    ),
                    None => format!("mesh {} primitive {}", mesh.index(), prim.index()),
                };
                match prim.mode() {
                    Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => {
                        report.skipped_non_triangle += 1;
                        continue;
                    }
                    Mode::TriangleStrip | Mode::TriangleFan => report.converted_strips_fans += 1,
                    Mode::Triangles => {}
                }
                report.primitives += 1;
                parts.push(read_primitive(&prim, buffers, world, &what)?);
            }
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world));
        }
    }

    if report.primitives == 0 {
        return Err(if report.skipped_non_triangle > 0 {
            format!(
                "no triangles: the scene has only points or lines primitives ({} of them); \
                 texsyn needs a triangle mesh (export surfaces, not curves or point clouds)",
                report.skipped_non_triangle
            )
        } else {
            "no triangles: the scene contains no mesh (is it the right file, and is the mesh \
             attached to a node of the scene?)"
                .into()
        });
    }
    let mesh = merge(parts)?;
    if mesh.triangles.is_empty() {
        return Err("no triangles: every triangle primitive is empty".into());
    }
    Ok((mesh, report))
}

/// Parent of every node; errors when the hierarchy is not a forest (glTF requires one:
/// a node with two parents could otherwise be instantiated exponentially often, and a
/// cycle forever).
fn node_parents(doc: &gltf::Document) -> std::result::Result<Vec<Option<usize>>, String> {
    let n = doc.nodes().len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for node in doc.nodes() {
        for child in node.children() {
            let c = child.index();
            if c == node.index() {
                return Err(format!("node {c} is its own child"));
            }
            if let Some(p) = parent[c] {
                return Err(format!(
                    "node {c} is a child of both node {p} and node {}; glTF node hierarchies \
                     must be trees",
                    node.index()
                ));
            }
            parent[c] = Some(node.index());
        }
    }
    // Walk up from every node; a walk meeting itself is a cycle. 0 = unknown,
    // usize::MAX = reaches a root, s + 1 = on the walk started at node s.
    let mut state = vec![0usize; n];
    for start in 0..n {
        let mut cur = start;
        while state[cur] != usize::MAX {
            if state[cur] == start + 1 {
                return Err(format!(
                    "the node hierarchy has a cycle through node {cur}; glTF node hierarchies \
                     must be trees"
                ));
            }
            state[cur] = start + 1;
            match parent[cur] {
                Some(p) => cur = p,
                None => break,
            }
        }
        let mut cur = start;
        while state[cur] == start + 1 {
            state[cur] = usize::MAX;
            match parent[cur] {
                Some(p) => cur = p,
                None => break,
            }
        }
    }
    Ok(parent)
}

/// Concatenates the parts (indices offset); an attribute missing from any part is
/// dropped from the result (normals: left empty, to be computed).
fn merge(parts: Vec<Part>) -> std::result::Result<Mesh, String> {
    let total: usize = parts.iter().map(|p| p.positions.len()).sum();
    if u32::try_from(total).is_err() {
        return Err(format!("{total} vertices in all, more than 2^32"));
    }
    let all_normals = parts.iter().all(|p| p.normals.is_some());
    let all_uvs = parts.iter().all(|p| p.uvs.is_some());
    let all_tangents = parts.iter().all(|p| p.tangents.is_some());
    let mut mesh = Mesh::default();
    mesh.positions.reserve(total);
    let mut uvs = Vec::with_capacity(if all_uvs { total } else { 0 });
    let mut tangents = Vec::with_capacity(if all_tangents { total } else { 0 });
    for part in parts {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(part.positions);
        if all_normals {
            mesh.normals.extend(part.normals.unwrap_or_default());
        }
        if all_uvs {
            uvs.extend(part.uvs.unwrap_or_default());
        }
        if all_tangents {
            tangents.extend(part.tangents.unwrap_or_default());
        }
        mesh.triangles
            .extend(part.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    mesh.uvs = all_uvs.then_some(uvs);
    mesh.tangents = all_tangents.then_some(tangents);
    Ok(mesh)
}

//! Reading one mesh primitive: every accessor's type and byte range checked before its
//! data is read, then positions, normals, uvs and tangents taken to world space.

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use gltf::Semantic;

use super::scene::Part;

fn dims_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

fn type_name(t: DataType) -> &'static str {
    match t {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

/// Checks an accessor's type and that every byte it reads (dense and sparse) lies inside
/// its buffer view and buffer, so gltf's reader neither panics nor comes up short.
fn check_accessor(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    what: &str,
    dims: Dimensions,
    types: &[DataType],
) -> std::result::Result<(), String> {
    let i = acc.index();
    let (d, t) = (acc.dimensions(), acc.data_type());
    if d != dims || !types.contains(&t) {
        let expected: Vec<&str> = types.iter().map(|&t| type_name(t)).collect();
        return Err(format!(
            "{what}: accessor {i} is {} of {}; texsyn reads {} of {}",
            dims_name(d),
            type_name(t),
            dims_name(dims),
            expected.join(" or ")
        ));
    }
    if t != DataType::F32 && d != Dimensions::Scalar && !acc.normalized() {
        return Err(format!(
            "{what}: accessor {i} holds unnormalized integers, which glTF does not allow here"
        ));
    }
    let count = acc.count();
    if count == 0 {
        return Err(format!("{what}: accessor {i} has count 0"));
    }
    let elem = acc.size();
    match (acc.view(), acc.sparse()) {
        (Some(view), _) => check_range(&view, acc.offset(), count, elem, buffers, what, i)?,
        (None, None) => return Err(format!("{what}: accessor {i} has no bufferView")),
        (None, Some(_)) => {}
    }
    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(format!(
                "{what}: sparse accessor {i} has {n} sparse values for {count} elements"
            ));
        }
        let indices = sparse.indices();
        check_range(
            &indices.view(),
            indices.offset(),
            n,
            indices.index_type().size(),
            buffers,
            what,
            i,
        )?;
        let values = sparse.values();
        check_range(&values.view(), values.offset(), n, elem, buffers, what, i)?;
    }
    Ok(())
}

/// `count` elements of `elem` bytes at `offset` in `view` (with its stride).
fn check_range(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    elem: usize,
    buffers: &[Vec<u8>],
    what: &str,
    accessor: usize,
) -> std::result::Result<(), String> {
    let v = view.index();
    let b = view.buffer().index();
    let buffer_len = buffers[b].len();
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|end| end > buffer_len)
    {
        return Err(format!(
            "{what}: bufferView {v} (bytes {}..+{}) lies outside buffer {b} ({buffer_len} bytes)",
            view.offset(),
            view.length()
        ));
    }
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "{what}: bufferView {v} has byteStride {stride}, smaller than the {elem}-byte \
             elements of accessor {accessor}"
        ));
    }
    let need = stride
        .checked_mul(count - 1)
        .and_then(|x| x.checked_add(elem))
        .and_then(|x| x.checked_add(offset));
    match need {
        Some(need) if need <= view.length() => Ok(()),
        _ => Err(format!(
            "{what}: accessor {accessor} ({count} elements from byte {offset}) reads past the \
             end of bufferView {v} ({} bytes): index or count out of range",
            view.length()
        )),
    }
}

pub(super) fn read_primitive(
    prim: &gltf::Primitive,
    buffers: &[Vec<u8>],
    world: Mat4,
    what: &str,
) -> std::result::Result<Part, String> {
    let Some(pos_acc) = prim.get(&Semantic::Positions) else {
        return Err(format!("{what} has no POSITION attribute"));
    };
    check_accessor(
        &pos_acc,
        buffers,
        &format!("{what} POSITION"),
        Dimensions::Vec3,
        &[DataType::F32],
    )?;
    let n = pos_acc.count();
    if u32::try_from(n).is_err() {
        return Err(format!("{what} has {n} vertices, more than 2^32"));
    }
    let attribute = |sem: Semantic, name: &str, dims, types: &[DataType]| {
        prim.get(&sem)
            .map(|acc| {
                let label = format!("{what} {name}");
                check_accessor(&acc, buffers, &label, dims, types)?;
                if acc.count() != n {
                    return Err(format!(
                        "{label}: accessor {} has {} elements, POSITION has {n}",
                        acc.index(),
                        acc.count()
                    ));
                }
                Ok(())
            })
            .transpose()
            .map(|o| o.is_some())
    };
    let has_normals = attribute(
        Semantic::Normals,
        "NORMAL",
        Dimensions::Vec3,
        &[DataType::F32],
    )?;
    let has_tangents = attribute(
        Semantic::Tangents,
        "TANGENT",
        Dimensions::Vec4,
        &[DataType::F32],
    )?;
    let has_uvs = attribute(
        Semantic::TexCoords(0),
        "TEXCOORD_0",
        Dimensions::Vec2,
        &[DataType::F32, DataType::U8, DataType::U16],
    )?;
    if let Some(acc) = prim.indices() {
        check_accessor(
            &acc,
            buffers,
            &format!("{what} indices"),
            Dimensions::Scalar,
            &[DataType::U8, DataType::U16, DataType::U32],
        )?;
    }

    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let short = |name: &str| format!("{what}: {name} could not be read (data out of range)");
    let exact = |len: usize, name: &str| {
        if len == n {
            Ok(())
        } else {
            Err(short(name))
        }
    };

    // Linear part for directions; cofactor matrix (= det * inverse transpose, defined
    // even for singular transforms) for normals.
    let linear = Mat3::from_mat4(world);
    let det = linear.determinant();
    let mirror = det < 0.0;
    let sign = if mirror { -1.0 } else { 1.0 };
    let normal_matrix = Mat3::from_cols(
        linear.y_axis.cross(linear.z_axis),
        linear.z_axis.cross(linear.x_axis),
        linear.x_axis.cross(linear.y_axis),
    ) * sign;

    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| short("POSITION"))?
        .map(|p| world.transform_point3(Vec3::from(p)))
        .collect();
    exact(positions.len(), "POSITION")?;
    let normals = if has_normals {
        let v: Vec<Vec3> = reader
            .read_normals()
            .ok_or_else(|| short("NORMAL"))?
            .map(|v| (normal_matrix * Vec3::from(v)).normalize_or_zero())
            .collect();
        exact(v.len(), "NORMAL")?;
        Some(v)
    } else {
        None
    };
    let tangents = if has_tangents {
        let v: Vec<Vec4> = reader
            .read_tangents()
            .ok_or_else(|| short("TANGENT"))?
            .map(|t| {
                let xyz = (linear * Vec3::new(t[0], t[1], t[2])).normalize_or_zero();
                let w = if t[3] < 0.0 { -sign } else { sign };
                xyz.extend(w)
            })
            .collect();
        exact(v.len(), "TANGENT")?;
        Some(v)
    } else {
        None
    };
    let uvs = if has_uvs {
        let v: Vec<Vec2> = reader
            .read_tex_coords(0)
            .ok_or_else(|| short("TEXCOORD_0"))?
            .into_f32()
            .map(Vec2::from)
            .collect();
        exact(v.len(), "TEXCOORD_0")?;
        Some(v)
    } else {
        None
    };

    let indices: Vec<u32> = match prim.indices() {
        Some(acc) => {
            let v: Vec<u32> = reader
                .read_indices()
                .ok_or_else(|| short("indices"))?
                .into_u32()
                .collect();
            if v.len() != acc.count() {
                return Err(short("indices"));
            }
            if let Some((k, &bad)) = v.iter().enumerate().find(|(_, &i)| i as usize >= n) {
                return Err(format!(
                    "{what}: index {bad} (entry {k} of accessor {}) is out of range: the \
                     primitive has {n} vertices",
                    acc.index()
                ));
            }
            v
        }
        None => (0..n as u32).collect(),
    };

    let mut triangles: Vec<[u32; 3]> = match prim.mode() {
        Mode::Triangles => {
            if !indices.len().is_multiple_of(3) {
                return Err(format!(
                    "{what}: {} vertex indices is not a multiple of 3 (mode TRIANGLES)",
                    indices.len()
                ));
            }
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
        // glTF 2.0 section 3.7.2.1: p_i = {v_i, v_(i+(1+i%2)), v_(i+(2-i%2))}.
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[0], w[2], w[1]]
                }
            })
            .collect(),
        // p_i = {v_(i+1), v_(i+2), v_0}.
        Mode::TriangleFan => indices
            .windows(2)
            .skip(1)
            .map(|w| [w[0], w[1], indices[0]])
            .collect(),
        _ => unreachable!("non-triangle modes are skipped by the caller"),
    };
    if mirror {
        // A negative determinant turns the winding clockwise; restore counter-clockwise.
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }

    Ok(Part {
        positions,
        normals,
        uvs,
        tangents,
        triangles,
    })
}

//! Cameras: the orbit around a mesh's bounding sphere, the view uniform of one camera,
//! and the CPU twin of the shader's lighting.

use glam::{Mat4, Vec3, Vec4};

use super::inputs::ViewUniform;
use super::{Camera, AMBIENT, LIGHT_DIRECTION, ORBIT_ELEVATION_DEG, ORBIT_FOV_DEG};
use crate::error::{Error, Result};
use crate::surface::mesh::Mesh;

/// The bounding sphere of the mesh's bounding box: (centre, radius).
pub(super) fn bounding_sphere(mesh: &Mesh) -> (Vec3, f32) {
    let mut min = Vec3::splat(f32::INFINITY);
    let mut max = Vec3::splat(f32::NEG_INFINITY);
    for p in &mesh.positions {
        min = min.min(*p);
        max = max.max(*p);
    }
    if !min.is_finite() || !max.is_finite() {
        return (Vec3::ZERO, 1.0);
    }
    let centre = 0.5 * (min + max);
    let radius = 0.5 * (max - min).length();
    (
        centre,
        radius.max(1e-6 * centre.length()).max(f32::MIN_POSITIVE),
    )
}

/// The cameras [`render_views`](super::render_views) uses: `views` cameras orbiting the
/// mesh (see the module documentation), all at the same distance from the centre of its
/// bounding box: the smallest at which every vertex is inside every view, plus a 5% margin.
pub fn orbit_cameras(mesh: &Mesh, views: u32) -> Vec<Camera> {
    let (centre, radius) = bounding_sphere(mesh);
    let tan = (ORBIT_FOV_DEG * 0.5).to_radians().tan() / 1.05;
    let elevation = ORBIT_ELEVATION_DEG.to_radians();
    let directions: Vec<Vec3> = (0..views)
        .map(|i| {
            let azimuth = (i as f32 * 360.0 / views as f32).to_radians();
            Vec3::new(
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
                elevation.cos() * azimuth.cos(),
            )
        })
        .collect();
    // Vertex p (offset o from the centre) is in the view from centre + d * dir when
    // |o . right| and |o . up| <= tan * (d - o . dir).
    let mut distance = radius * 1e-3;
    for dir in &directions {
        let right = (-*dir).cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(-*dir);
        for p in &mesh.positions {
            let o = *p - centre;
            let lateral = o.dot(right).abs().max(o.dot(up).abs());
            distance = distance.max(o.dot(*dir) + lateral / tan);
        }
    }
    if !distance.is_finite() {
        distance = radius / tan;
    }
    directions
        .iter()
        .map(|dir| Camera {
            eye: centre + distance * *dir,
            target: centre,
            up: Vec3::Y,
            fov_y_deg: ORBIT_FOV_DEG,
        })
        .collect()
}

/// The shade factor the renderer applies to a texel's colour, for a unit normal in view
/// space already turned towards the viewer: `AMBIENT + (1 - AMBIENT) * max(0, n . l)`.
pub fn shade(view_normal: Vec3) -> f32 {
    let l = Vec3::from(LIGHT_DIRECTION).normalize();
    AMBIENT + (1.0 - AMBIENT) * view_normal.dot(l).max(0.0)
}

/// View uniforms of `camera` for a mesh with bounding sphere (centre, radius).
pub(super) fn view_uniform(camera: &Camera, centre: Vec3, radius: f32) -> Result<ViewUniform> {
    let forward = camera.target - camera.eye;
    let fov_ok = camera.fov_y_deg.is_finite() && camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0;
    if !fov_ok
        || !camera.eye.is_finite()
        || forward.length_squared() == 0.0
        || !forward.is_finite()
        || forward.cross(camera.up).length_squared() == 0.0
    {
        return Err(Error::InvalidParameter(format!(
            "render: invalid camera {camera:?} (eye and target must differ, up must not be \
             parallel to the view direction, fov in (0, 180) degrees)"
        )));
    }
    let view = Mat4::look_at_rh(camera.eye, camera.target, camera.up);
    // Depth range from the bounding sphere, along the view direction.
    let ahead = (centre - camera.eye).dot(forward.normalize());
    let far = (ahead + radius * 1.01).max(radius * 1e-3);
    let near = (ahead - radius * 1.01).max(far * 1e-4);
    let proj = Mat4::perspective_rh(camera.fov_y_deg.to_radians(), 1.0, near, far);
    let l = Vec3::from(LIGHT_DIRECTION).normalize();
    Ok(ViewUniform {
        view_proj: (proj * view).to_cols_array_2d(),
        view: view.to_cols_array_2d(),
        light: Vec4::new(l.x, l.y, l.z, AMBIENT).to_array(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::render::{AMBIENT, LIGHT_DIRECTION};

    #[test]
    fn orbit_cameras_look_at_the_centre_from_the_same_distance() {
        let mesh = Mesh {
            positions: vec![Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 2.0, 0.0)],
            ..Mesh::default()
        };
        let cams = orbit_cameras(&mesh, 4);
        assert_eq!(cams.len(), 4);
        let centre = Vec3::new(1.0, 1.0, -1.0);
        let d0 = (cams[0].eye - centre).length();
        for c in &cams {
            assert!((c.target - centre).length() < 1e-5);
            assert!(((c.eye - centre).length() - d0).abs() < 1e-4);
            assert!(c.eye.y > centre.y, "slight elevation");
        }
        // First view from +Z (glTF front), second from +X.
        assert!(cams[0].eye.z > centre.z && (cams[0].eye.x - centre.x).abs() < 1e-4);
        assert!(cams[1].eye.x > centre.x);
    }

    #[test]
    fn shade_is_one_facing_the_light() {
        let l = Vec3::from(LIGHT_DIRECTION).normalize();
        assert!((shade(l) - 1.0).abs() < 1e-6);
        assert!((shade(-l) - AMBIENT).abs() < 1e-6);
    }
}

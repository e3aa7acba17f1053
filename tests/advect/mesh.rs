//! Advection over a surface atlas: velocities from 3D vectors, GPU = CPU.

use texsyn::flow::Flow;
use texsyn::gpu::advect::AdvectOptions;
use texsyn::SynthParams;

use crate::harness::*;

/// Advection over a surface atlas: velocities from 3D vectors projected into the atlas,
/// gutters refilled through the indirection maps; GPU = CPU.
#[cfg(feature = "xatlas")]
#[test]
fn surface_advection_gpu_matches_cpu() {
    let gravel = Synth::gravel(32);
    let a = gravel.analysis.clone();
    let mut mesh = texsyn::surface::Mesh::cube(1.0, 2);
    mesh.validate_and_repair().unwrap();
    let opts = texsyn::surface::pipeline::SurfaceOptions {
        atlas: texsyn::surface::atlas::AtlasOptions::for_size(64),
        ..Default::default()
    };
    let prep = texsyn::surface::pipeline::prepare(&mesh, a.levels.len(), &opts).unwrap();
    let params = texsyn::surface::pipeline::atlas_params(&prep, &SynthParams::default());
    let o = AdvectOptions::default();
    // Room for the fade state too (frames 5 and 6 fade).
    let mut frames = FrameLoop::mirrored_with_fade_room(&gravel, &params, o);
    assert!(!frames.plan().surface_words().0.is_empty());
    let flow = Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega: 0.2,
    };
    let v = texsyn::surface::flow::atlas_velocity(&prep, &flow, 0.0).unwrap();
    assert!(v.iter().any(|p| p[0] != 0.0 || p[1] != 0.0));
    // Frame 3 re-synthesizes two levels below the finest (their fills included), frame
    // 4 keeps the look (`keep_look`: remade levels on the atlas), frames 5 and 6 fade
    // (the first without fade state, the second reading it).
    for f in 0..6u64 {
        let o = AdvectOptions {
            resynthesize: if f == 2 { 2 } else { 0 },
            keep_look: f >= 3,
            levels: if f >= 2 { 4 } else { o.levels },
            fade: if f >= 4 { 4 } else { 0 },
            // Anchored renewals on the atlas (anchors outside the charts skipped).
            anchor_spacing: if f >= 3 { 4 } else { 0 },
            anchor_upsample: if f == 4 { 0.5 } else { 0.0 },
            ..o
        };
        frames.set_options(o);
        let out = frames.step_mirrored(&v, 1.0);
        assert!(frames.matches_mirror_start(), "frame {} differs", f + 1);
        assert_eq!(frames.rgba(), rgba8(&out), "frame {}", f + 1);
    }
    // Per-vertex vectors: the wrong count and NaN are errors.
    let n = prep.atlas.mesh.positions.len();
    assert!(texsyn::surface::flow::atlas_velocity_from_vertices(
        &prep,
        &vec![glam::Vec3::X; n - 1]
    )
    .is_err());
    let mut bad = vec![glam::Vec3::X; n];
    bad[0].x = f32::NAN;
    assert!(texsyn::surface::flow::atlas_velocity_from_vertices(&prep, &bad).is_err());
    let ok = texsyn::surface::flow::atlas_velocity_from_vertices(&prep, &vec![glam::Vec3::X; n])
        .unwrap();
    assert_eq!(ok.len(), 64 * 64);
    // Vectors per vertex of the mesh given to `prepare` (a torus, whose vertices the
    // atlas splits where its charts are cut): carried onto the atlas mesh's vertices,
    // they give the same field as the same function of position given per atlas vertex.
    let mut torus = texsyn::surface::Mesh::torus(1.0, 0.4, 16, 8);
    torus.validate_and_repair().unwrap();
    let prep = texsyn::surface::pipeline::prepare(&torus, a.levels.len(), &opts).unwrap();
    let n = prep.atlas.mesh.positions.len();
    assert!(n > torus.positions.len(), "no vertex was split");
    let swirl = |p: &glam::Vec3| glam::Vec3::new(-p.z, 0.25 * p.x, p.x + p.y);
    let from_mesh = texsyn::surface::flow::atlas_velocity_from_mesh_vertices(
        &prep,
        &torus.positions.iter().map(swirl).collect::<Vec<_>>(),
    )
    .unwrap();
    let from_atlas = texsyn::surface::flow::atlas_velocity_from_vertices(
        &prep,
        &prep
            .atlas
            .mesh
            .positions
            .iter()
            .map(swirl)
            .collect::<Vec<_>>(),
    )
    .unwrap();
    assert_eq!(from_mesh, from_atlas);
    assert!(from_mesh.iter().any(|v| v[0] != 0.0));
    // The atlas mesh's count is the wrong one here.
    let e =
        texsyn::surface::flow::atlas_velocity_from_mesh_vertices(&prep, &vec![glam::Vec3::X; n]);
    assert!(e.is_err());
}

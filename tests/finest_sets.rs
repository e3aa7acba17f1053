//! An analysis without the finest level's similarity sets (`AnalysisOptions::finest_sets
//! = false`, what `texsyn synth` from an image uses): the same synthesis bytes as the
//! full analysis wherever the finest level is not corrected, and a clear error wherever
//! it would be.

mod common;
use common::ctx;

use std::sync::Arc;

use texsyn::analysis::{analyze, Analysis, AnalysisOptions};
use texsyn::field::Field;
use texsyn::gpu::advect::{AdvectOptions, Advection};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::passes::synthesize_cpu;
use texsyn::surface::atlas::AtlasOptions;
use texsyn::surface::mesh::Mesh;
use texsyn::surface::pipeline::{self, SurfaceOptions};
use texsyn::{Error, SynthParams};

/// The full and the lean analysis of a 40x40 crop.
fn analyses(tileable: bool) -> (Arc<Analysis>, Arc<Analysis>) {
    let ex = common::gravel_crop(40);
    let opts = AnalysisOptions {
        tileable: Some(tileable),
        ..AnalysisOptions::default()
    };
    let full = analyze(&ex, &opts, |_| {}).unwrap();
    let lean = analyze(
        &ex,
        &AnalysisOptions {
            finest_sets: false,
            ..opts
        },
        |_| {},
    )
    .unwrap();
    (Arc::new(full), Arc::new(lean))
}

#[test]
fn lean_analysis_differs_only_in_the_finest_sets() {
    for tileable in [false, true] {
        let (full, lean) = analyses(tileable);
        assert!(full.has_finest_sets());
        assert!(!lean.has_finest_sets());
        lean.validate().unwrap();
        let top = full.levels.len() - 1;
        assert!(lean.levels[top].offsets.is_empty());
        // Its tables go too (only the finest correction reads them); level 0, never
        // corrected, has none in either analysis.
        assert!(full.has_tables(top) && !lean.has_tables(top));
        assert!(lean.levels[top].et.is_empty() && lean.levels[top].qe.is_empty());
        assert!(!full.has_tables(0) && !lean.has_tables(0));
        assert!((1..top).all(|l| full.has_tables(l) && lean.has_tables(l)));
        // The full analysis really searched them (not all the coherent candidate).
        assert!(full.levels[top].offsets.iter().any(|o| *o != [0, 0]));
        let mut patched = (*lean).clone();
        patched.levels[top] = full.levels[top].clone();
        assert_eq!(patched, *full, "tileable {tileable}: other tables differ");
    }
    // k = 1 has no sets to leave out, but the finest tables still go.
    let ex = common::gravel_crop(40);
    let k1 = AnalysisOptions {
        k: 1,
        finest_sets: false,
        ..AnalysisOptions::default()
    };
    let a = analyze(&ex, &k1, |_| {}).unwrap();
    assert!(a.has_finest_sets() && !a.has_tables(a.levels.len() - 1));
    a.validate().unwrap();
    let params = SynthParams {
        width: 24,
        height: 24,
        finest_passes: 1,
        ..SynthParams::default()
    };
    assert!(matches!(
        synthesize_cpu(&a, &params),
        Err(Error::InvalidParameter(m)) if m.contains("finest_sets")
    ));
}

#[test]
fn lean_analysis_synthesizes_the_same_bytes() {
    let rotate = Field::Constant {
        angle: 0.5,
        scale: [1.0, 1.0],
        shear: 0.0,
    };
    for tileable in [false, true] {
        let (full, lean) = analyses(tileable);
        let gpu_full = GpuSynthesizer::new(ctx(), full.clone()).unwrap();
        let gpu_lean = GpuSynthesizer::new(ctx(), lean.clone()).unwrap();
        for field in [None, Some(rotate.clone())] {
            let params = SynthParams {
                width: 45,
                height: 38,
                origin: [-7, 12],
                seed: 9,
                field: field.clone(),
                ..SynthParams::default()
            };
            let a = gpu_full.synthesize_to_host(&params).unwrap();
            let b = gpu_lean.synthesize_to_host(&params).unwrap();
            assert_eq!(
                a, b,
                "tileable {tileable}, field {field:?}: GPU outputs differ"
            );
            let c = synthesize_cpu(&lean, &params).unwrap();
            assert_eq!(
                c, b,
                "tileable {tileable}, field {field:?}: CPU mirror differs"
            );
        }
        // Files written before level 0 went without tables carry them (never read): they
        // still load and synthesize the same bytes, which needs every later level's
        // tables found where they are.
        let mut old = (*lean).clone();
        old.levels[0].et = full.levels[1]
            .et
            .iter()
            .map(|e| e.map(|v| v ^ 0x5a5))
            .collect();
        old.levels[0].qe = full.levels[1]
            .qe
            .iter()
            .map(|e| e.map(|v| v ^ 0x3c3))
            .collect();
        let old = Analysis::from_bytes(&old.to_bytes(), std::path::Path::new("old.tsa")).unwrap();
        assert!(old.has_tables(0) && old.table_base(1) == old.levels[0].et.len());
        let old = Arc::new(old);
        let gpu_old = GpuSynthesizer::new(ctx(), old.clone()).unwrap();
        let params = SynthParams {
            width: 45,
            height: 38,
            origin: [-7, 12],
            seed: 9,
            ..SynthParams::default()
        };
        let b = gpu_lean.synthesize_to_host(&params).unwrap();
        assert_eq!(
            gpu_old.synthesize_to_host(&params).unwrap(),
            b,
            "tileable {tileable}: level 0 tables changed the GPU output"
        );
        assert_eq!(
            synthesize_cpu(&old, &params).unwrap(),
            b,
            "tileable {tileable}: level 0 tables changed the CPU output"
        );
    }
}

/// `texsyn surface` analyses without the finest sets too: the atlas is the same.
#[test]
fn lean_analysis_synthesizes_the_same_atlas() {
    let (full, lean) = analyses(false);
    let mut mesh = Mesh::cube(1.0, 2);
    mesh.validate_and_repair().unwrap();
    let opts = SurfaceOptions {
        atlas: AtlasOptions::for_size(64),
        ..SurfaceOptions::default()
    };
    let prep = pipeline::prepare(&mesh, full.levels.len(), &opts).unwrap();
    let base = SynthParams {
        seed: 5,
        ..SynthParams::default()
    };
    let run = |a: &Arc<Analysis>| {
        let synth = GpuSynthesizer::new(ctx(), a.clone()).unwrap();
        pipeline::synthesize(&synth, &prep, &base, &[]).unwrap().0
    };
    assert_eq!(run(&full), run(&lean), "atlas syntheses differ");
}

#[test]
fn lean_analysis_refuses_a_corrected_finest_level() {
    let (full, lean) = analyses(false);
    let params = SynthParams {
        width: 32,
        height: 32,
        finest_passes: 1,
        ..SynthParams::default()
    };
    let gpu_lean = Arc::new(GpuSynthesizer::new(ctx(), lean.clone()).unwrap());
    let expect_refusal = |r: Result<(), Error>, what: &str| match r {
        Err(Error::InvalidParameter(m)) => assert!(
            m.contains("finest level") && m.contains("finest_sets"),
            "{what}: unclear message {m:?}"
        ),
        other => panic!("{what}: expected a refusal, got {other:?}"),
    };
    expect_refusal(
        gpu_lean.synthesize_to_host(&params).map(|_| ()),
        "GPU synthesis",
    );
    expect_refusal(synthesize_cpu(&lean, &params).map(|_| ()), "CPU synthesis");
    // Advection corrects the finest level every frame.
    expect_refusal(
        Advection::new(
            gpu_lean,
            &SynthParams {
                width: 32,
                height: 32,
                ..SynthParams::default()
            },
            AdvectOptions::default(),
        )
        .map(|_| ()),
        "advection",
    );
    // The full analysis takes the same parameters.
    let gpu_full = GpuSynthesizer::new(ctx(), full).unwrap();
    gpu_full.synthesize_to_host(&params).unwrap();
}

#[test]
fn lean_analysis_file_round_trip() {
    let (_, lean) = analyses(true);
    let path = std::path::Path::new("lean.tsa");
    let bytes = lean.to_bytes();
    let back = Analysis::from_bytes(&bytes, path).unwrap();
    assert_eq!(back, *lean);
    assert!(!back.has_finest_sets());
    let dir = std::env::temp_dir().join(format!("texsyn-lean-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("lean.tsa");
    lean.save(&file).unwrap();
    assert_eq!(Analysis::load(&file).unwrap(), *lean);
    std::fs::remove_dir_all(&dir).unwrap();

    // Only the finest level may go without its sets.
    let mut coarse = (*lean).clone();
    let l = coarse.levels.len() - 2;
    coarse.levels[l].offsets = Default::default();
    match coarse.validate() {
        Err(Error::InvalidParameter(m)) => assert!(m.contains("offsets"), "{m}"),
        other => panic!("expected a refusal, got {other:?}"),
    }
    match Analysis::from_bytes(&coarse.to_bytes(), path) {
        Err(Error::BadAnalysisFile { reason, .. }) => {
            assert!(reason.contains("offsets"), "{reason}")
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
}

// Development driver: analyse an exemplar, synthesize on CPU and GPU, compare, save.
use std::sync::Arc;
use std::time::Instant;
use texsyn::gpu::{synth::GpuSynthesizer, GpuContext};

fn main() -> texsyn::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let ex = texsyn::image_io::load_exemplar(std::path::Path::new(&args[1]))?;
    let size: u32 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(128);
    let t = Instant::now();
    let mut opts = texsyn::AnalysisOptions::default();
    if let Ok(k) = std::env::var("TS_K") {
        opts.k = k.parse().unwrap();
    }
    let a = texsyn::analysis::analyze(&ex, &opts, |_| {})?;
    eprintln!(
        "analysis {:?} tileable={} levels={}",
        t.elapsed(),
        a.tileable,
        a.levels.len()
    );
    for (i, l) in a.levels.iter().enumerate() {
        eprintln!(
            "  level {i}: h={} residual {:.3} runtime {:.3} shift {}",
            l.spacing, l.residual_variance, l.runtime_residual_variance, l.shift
        );
    }
    let env = |k: &str| std::env::var(k).ok();
    let mut params = texsyn::SynthParams {
        width: size,
        height: size,
        ..Default::default()
    };
    if let Some(r) = env("TS_R") {
        params.randomness = r.split(',').map(|x| x.parse().unwrap()).collect();
    }
    if let Some(r) = env("TS_PASSES") {
        params.passes = r.parse().unwrap();
    }
    if let Some(r) = env("TS_COH") {
        params.coherence = r.parse().unwrap();
    }
    if let Some(r) = env("TS_SEED") {
        params.seed = r.parse().unwrap();
    }
    let t = Instant::now();
    let cpu = texsyn::passes::synthesize_cpu(&a, &params)?;
    eprintln!("cpu {:?}", t.elapsed());
    let ctx = GpuContext::headless()?;
    eprintln!("{}", ctx.describe());
    let g = GpuSynthesizer::new(&ctx, Arc::new(a.clone()))?;
    let _ = g.synthesize_to_host(&ctx, &params)?;
    let t = Instant::now();
    let gpu = g.synthesize_to_host(&ctx, &params)?;
    eprintln!("gpu {:?}", t.elapsed());
    let diff = cpu
        .coords
        .iter()
        .zip(&gpu.coords)
        .filter(|(a, b)| a != b)
        .count();
    eprintln!("coords differing: {diff} / {}", cpu.coords.len());
    let exf = texsyn::quality::FloatImage::from_exemplar(&ex);
    let gpu = if std::env::var_os("TS_CPU").is_some() {
        cpu.clone()
    } else {
        gpu
    };
    let out = texsyn::quality::FloatImage::from_rgba8(size, size, &gpu.colors)?;
    let out = if ex.channels == 1 { out.to_grey() } else { out };
    let rep = texsyn::quality::evaluate(
        &exf,
        &out,
        3,
        Some(texsyn::quality::CoordMap {
            coords: &gpu.coords,
            width: size,
            height: size,
            tileable: a.tileable,
        }),
    )?;
    println!("{}", rep.to_json());
    let bytes: Vec<u8> = gpu.colors.iter().flatten().copied().collect();
    texsyn::image_io::save_image_atomic(
        std::path::Path::new("/tmp/out.png"),
        size,
        size,
        ex.channels,
        &bytes,
    )?;
    Ok(())
}

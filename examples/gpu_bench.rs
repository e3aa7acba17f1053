//! GPU benchmark: times every kind of synthesis texsyn runs on one device and prints a
//! markdown table (case, size, median ms, min ms, runs) headed by the adapter, backend,
//! driver, date (UTC) and texsyn version.
//!
//! ```text
//! cargo build --release --example gpu_bench
//! target/release/examples/gpu_bench [--quick] [--budget-s S] [--out FILE]
//! tools/gpu_bench.sh OUT.md [--quick]          # the same, with a time limit
//! ```
//!
//! Each case is built once (analysis, atlas, pipelines in the warm-up runs), then timed
//! over several runs; every run ends with a device sync (`wait_idle`), so a time is
//! submit-to-finish wall time of the GPU work (plus the read-back where the case says
//! so). Cases: 2D synthesis at 256..4096, a larger output assembled from windows,
//! anisometric synthesis along a vortex field, magnification x4, atlas synthesis on the
//! bundled bunny and one advection step.
//!
//! `--quick` runs every case at reduced sizes and runs, for a CPU device (lavapipe).
//! Cases still waiting when the time budget (`--budget-s`, default 150 s; 100 s with
//! `--quick`) is spent are listed as skipped, so the table is always written.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use texsyn::field::Field;
use texsyn::flow::Flow;
use texsyn::GpuContext;
use texsyn::GpuSynthesizer;
use texsyn::{AdvectOptions, Advection};
use texsyn::{Session, SynthParams};

/// The bundled exemplar and mesh, relative to the repository.
const GRAVEL: &str = "assets/gravel.png";
#[cfg(all(feature = "gltf", feature = "xatlas"))]
const BUNNY: &str = "assets/meshes/bunny.glb";

/// `rel` in the repository the binary was built in (`target/release/examples/gpu_bench`
/// is three levels below it), so a copy of the repository and its `target/` elsewhere
/// still finds its assets; else in the directory the crate was compiled in.
fn asset(rel: &str) -> PathBuf {
    let from_exe = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.ancestors().nth(4).map(|root| root.join(rel)));
    match from_exe {
        Some(path) if path.is_file() => path,
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join(rel),
    }
}

/// Sizes and repetitions of one benchmark configuration.
struct Config {
    synth_sizes: &'static [u32],
    /// Side of the output assembled from windows, tried first; halved while it fails.
    windows_side: u32,
    /// Window side forced in `--quick` (so that several windows are assembled); `None`:
    /// the library's choice (the largest the device takes).
    windows_forced: Option<u32>,
    aniso_size: u32,
    magnify_size: u32,
    atlas_sizes: &'static [u32],
    advect_sizes: &'static [u32],
    warmup: u32,
    runs: u32,
    /// Runs of the cases that take seconds each (4096, windows, 2048 atlas).
    big_runs: u32,
    advect_warmup: u32,
    advect_runs: u32,
    budget: Duration,
}

const FULL: Config = Config {
    synth_sizes: &[256, 512, 1024, 2048, 4096],
    windows_side: 8192,
    windows_forced: None,
    aniso_size: 1024,
    magnify_size: 1024,
    atlas_sizes: &[1024, 2048],
    advect_sizes: &[512, 1024],
    warmup: 2,
    runs: 7,
    big_runs: 3,
    advect_warmup: 4,
    advect_runs: 20,
    budget: Duration::from_secs(150),
};

const QUICK: Config = Config {
    synth_sizes: &[128, 256, 512],
    windows_side: 1024,
    windows_forced: Some(512),
    aniso_size: 256,
    magnify_size: 128,
    atlas_sizes: &[256, 512],
    advect_sizes: &[128, 256],
    warmup: 1,
    runs: 5,
    big_runs: 3,
    advect_warmup: 2,
    advect_runs: 9,
    budget: Duration::from_secs(100),
};

/// One row of the table.
struct Row {
    case: String,
    size: String,
    /// Median and min in ms, and the number of timed runs; or why there is none.
    result: Result<(f64, f64, u32), String>,
}

/// Runs `f` `warmup` times untimed, then `runs` times timed; every call must end with
/// the device idle.
fn time_runs(
    warmup: u32,
    runs: u32,
    mut f: impl FnMut() -> texsyn::Result<()>,
) -> texsyn::Result<(f64, f64, u32)> {
    for _ in 0..warmup {
        f()?;
    }
    let mut ms = Vec::with_capacity(runs as usize);
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        f()?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    let n = ms.len();
    let median = if n % 2 == 1 {
        ms[n / 2]
    } else {
        (ms[n / 2 - 1] + ms[n / 2]) / 2.0
    };
    Ok((median, ms[0], n as u32))
}

/// The benchmark's state: the device, the time budget and the rows so far.
struct Bench {
    ctx: GpuContext,
    start: Instant,
    budget: Duration,
    rows: Vec<Row>,
}

impl Bench {
    /// Time one case (unless the budget is spent) and add its row.
    fn case(
        &mut self,
        case: &str,
        size: String,
        f: impl FnOnce(&GpuContext) -> texsyn::Result<(f64, f64, u32)>,
    ) {
        let result = if self.start.elapsed() >= self.budget {
            Err(format!(
                "skipped: time budget ({} s) spent",
                self.budget.as_secs()
            ))
        } else {
            eprintln!(
                "[{:6.1} s] {case} {size}",
                self.start.elapsed().as_secs_f64()
            );
            f(&self.ctx)
                .and_then(|r| self.ctx.take_uncaptured_errors().map(|()| r))
                .map_err(|e| format!("error: {e}"))
        };
        if let Err(e) = &result {
            eprintln!("  {e}");
        }
        self.rows.push(Row {
            case: case.to_string(),
            size,
            result,
        });
    }
}

fn main() {
    let mut quick = false;
    let mut out: Option<String> = None;
    let mut budget: Option<u64> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => quick = true,
            "--out" => out = args.next(),
            "--budget-s" => budget = args.next().and_then(|s| s.parse().ok()),
            "-h" | "--help" => {
                println!("usage: gpu_bench [--quick] [--budget-s SECONDS] [--out FILE]");
                return;
            }
            other => {
                eprintln!("gpu_bench: unknown argument '{other}' (see --help)");
                std::process::exit(2);
            }
        }
    }
    let mut config = if quick { QUICK } else { FULL };
    if let Some(s) = budget {
        config.budget = Duration::from_secs(s);
    }
    match run(&config, quick) {
        Ok(table) => {
            let written = match &out {
                Some(path) => std::fs::write(path, &table).map_err(|e| format!("{path}: {e}")),
                None => {
                    print!("{table}");
                    Ok(())
                }
            };
            if let Err(e) = written {
                eprintln!("gpu_bench: cannot write the table: {e}");
                std::process::exit(1);
            }
        }
        Err(e) => {
            eprintln!("gpu_bench: {e}");
            std::process::exit(1);
        }
    }
}

fn run(config: &Config, quick: bool) -> texsyn::Result<String> {
    let start = Instant::now();
    // Analysis of the bundled exemplar and the device (TEXSYN_BACKEND / TEXSYN_ADAPTER
    // choose another adapter).
    let session = Session::builder()
        .exemplar_path(asset(GRAVEL))
        .seed(1)
        .build()?;
    let ctx = session.context().clone();
    let synthesizer = Arc::clone(session.synthesizer());
    let setup = start.elapsed();
    let mut bench = Bench {
        ctx,
        start,
        budget: config.budget,
        rows: Vec::new(),
    };
    let base = SynthParams {
        seed: 1,
        ..session.params().clone()
    };
    let sized = |w: u32, h: u32| SynthParams {
        width: w,
        height: h,
        ..base.clone()
    };

    // 2D (isometric) synthesis, one piece, no read-back.
    for &n in config.synth_sizes {
        let runs = if n >= 4096 {
            config.big_runs
        } else {
            config.runs
        };
        let params = sized(n, n);
        bench.case("2D synthesis", format!("{n}x{n}"), |ctx| {
            if !synthesizer.fits(&params) {
                return Err(texsyn::Error::InvalidParameter(
                    "does not fit the device in one piece".into(),
                ));
            }
            time_runs(config.warmup, runs, || {
                synthesizer.synthesize(&params)?;
                ctx.wait_idle()
            })
        });
    }

    // A larger output assembled from windows on the host (read-back included).
    let mut side = config.windows_side;
    loop {
        let params = sized(side, side);
        let mut failed = false;
        bench.case(
            "2D from windows, read back",
            format!("{side}x{side}"),
            |ctx| {
                let r = time_runs(config.warmup.min(1), config.big_runs, || {
                    match config.windows_forced {
                        Some(w) => synthesizer
                            .synthesize_in_windows_sized(&params, &[], w, &mut |_, _| {})
                            .map(drop),
                        None => synthesizer
                            .synthesize_in_windows(&params, &[], |_, _| {})
                            .map(drop),
                    }?;
                    ctx.wait_idle()
                });
                failed = r.is_err();
                r
            },
        );
        if !failed || side <= 1024 {
            break;
        }
        // Too large for this machine: the row stays (with its error); try half.
        side /= 2;
    }

    // Anisometric synthesis along a vortex field.
    let n = config.aniso_size;
    let params = SynthParams {
        field: Some(Field::Vortex {
            center: [n as f64 / 2.0, n as f64 / 2.0],
            scale: 1.0,
        }),
        ..sized(n, n)
    };
    bench.case("anisometric (vortex field)", format!("{n}x{n}"), |ctx| {
        time_runs(config.warmup, config.runs, || {
            synthesizer.synthesize(&params)?;
            ctx.wait_idle()
        })
    });

    // Magnification x4: synthesis from the exemplar downsampled 4 times, rendered from
    // the full-resolution one.
    let n = config.magnify_size;
    bench.case(
        "magnify x4",
        format!("{n}x{n} -> {}x{}", 4 * n, 4 * n),
        |ctx| {
            let exemplar = texsyn::image_io::load_exemplar(&asset(GRAVEL))?;
            let (small, hi) = texsyn::image_io::downsample_exemplar(&exemplar, 4)?;
            let (hi_w, hi_h) = (small.width * 4, small.height * 4);
            let session = Session::builder()
                .exemplar(small)
                .context(ctx.clone())
                .build()?;
            let params = sized(n, n);
            time_runs(config.warmup, config.runs, || {
                session
                    .synthesizer()
                    .synthesize_magnified(&params, &hi, hi_w, hi_h, 4)?;
                ctx.wait_idle()
            })
        },
    );

    atlas_cases(&mut bench, config, &synthesizer, &base);

    // One advection step (GPU velocities, a vortex), after the first frame.
    for &n in config.advect_sizes {
        let params = sized(n, n);
        bench.case("advection step", format!("{n}x{n}"), |ctx| {
            let options = AdvectOptions::recommended(&params);
            let mut advection = Advection::new(Arc::clone(&synthesizer), &params, options)?;
            let v = Flow::Vortex {
                cx: 0.5,
                cy: 0.5,
                omega: 0.01,
            }
            .sample(n, n, 0.0)?;
            let velocity = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("gpu_bench velocity"),
                size: n as u64 * n as u64 * 8,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            ctx.queue
                .write_buffer(&velocity, 0, bytemuck::cast_slice(&v));
            ctx.wait_idle()?;
            time_runs(config.advect_warmup, config.advect_runs, || {
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                advection.encode_step(&mut encoder, &velocity, 1.0)?;
                ctx.queue.submit([encoder.finish()]);
                ctx.wait_idle()
            })
        });
    }

    Ok(table(&bench, config, quick, setup))
}

/// Atlas synthesis on the bundled bunny (atlas, field and maps prepared untimed).
#[cfg(all(feature = "gltf", feature = "xatlas"))]
fn atlas_cases(
    bench: &mut Bench,
    config: &Config,
    synthesizer: &GpuSynthesizer,
    base: &SynthParams,
) {
    use texsyn::surface::atlas::AtlasOptions;
    use texsyn::surface::pipeline::{self, SurfaceOptions};
    for &n in config.atlas_sizes {
        let runs = if n >= 2048 {
            config.big_runs
        } else {
            config.runs
        };
        bench.case("atlas (bunny.glb)", format!("{n}x{n}"), |ctx| {
            let (mut mesh, _) = texsyn::surface::gltf_io::load_mesh(&asset(BUNNY))?;
            mesh.validate_and_repair()?;
            let options = SurfaceOptions {
                atlas: AtlasOptions::for_size(n),
                ..SurfaceOptions::default()
            };
            let prepared =
                pipeline::prepare(&mesh, pipeline::levels_of(synthesizer.analysis()), &options)?;
            let params = pipeline::atlas_params(&prepared, base);
            time_runs(config.warmup, runs, || {
                synthesizer.synthesize(&params)?;
                ctx.wait_idle()
            })
        });
    }
}

#[cfg(not(all(feature = "gltf", feature = "xatlas")))]
fn atlas_cases(bench: &mut Bench, config: &Config, _: &GpuSynthesizer, _: &SynthParams) {
    for &n in config.atlas_sizes {
        bench.rows.push(Row {
            case: "atlas (bunny.glb)".into(),
            size: format!("{n}x{n}"),
            result: Err("skipped: built without the gltf and xatlas features".into()),
        });
    }
}

/// The markdown report: header lines, then the table.
fn table(bench: &Bench, config: &Config, quick: bool, setup: Duration) -> String {
    let info = &bench.ctx.adapter_info;
    let mut s = String::new();
    s.push_str("## texsyn GPU benchmark\n\n");
    s.push_str(&format!(
        "- adapter: {} ({:?}, vendor 0x{:04x}, device 0x{:04x})\n",
        info.name, info.device_type, info.vendor, info.device
    ));
    s.push_str(&format!("- backend: {:?}\n", info.backend));
    s.push_str(&format!("- driver: {} {}\n", info.driver, info.driver_info));
    s.push_str(&format!("- date: {} UTC\n", utc_now()));
    s.push_str(&format!("- texsyn: {}\n", env!("CARGO_PKG_VERSION")));
    s.push_str(&format!(
        "- host: {} CPU threads\n",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    ));
    s.push_str(&format!(
        "- mode: {}; exemplar assets/gravel.png; {} warm-up + {} timed runs ({} for the \
         largest cases, {} + {} advection steps); each run ends with a device sync\n",
        if quick {
            "--quick (reduced sizes)"
        } else {
            "full"
        },
        config.warmup,
        config.runs,
        config.big_runs,
        config.advect_warmup,
        config.advect_runs
    ));
    s.push_str(&format!(
        "- setup (analysis + device): {:.0} ms; total: {:.1} s\n\n",
        setup.as_secs_f64() * 1e3,
        bench.start.elapsed().as_secs_f64()
    ));
    s.push_str("| case | size | median ms | min ms | runs |\n");
    s.push_str("|---|---|---:|---:|---:|\n");
    for row in &bench.rows {
        match &row.result {
            Ok((median, min, runs)) => s.push_str(&format!(
                "| {} | {} | {median:.2} | {min:.2} | {runs} |\n",
                row.case, row.size
            )),
            Err(e) => s.push_str(&format!(
                "| {} | {} | {} | | 0 |\n",
                row.case,
                row.size,
                e.replace('|', "/").replace('\n', " ")
            )),
        }
    }
    s
}

/// The current time as `YYYY-MM-DD HH:MM:SS` (UTC).
fn utc_now() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02}",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

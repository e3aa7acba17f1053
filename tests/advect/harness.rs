//! The frame loop of the advection tests: an exemplar analysed with its synthesizer
//! ([`Synth`]), an [`Advection`] over it with, optionally, the CPU mirror of its
//! coordinates ([`FrameLoop`]), stepped frame by frame; and the flows the tests use.

use std::sync::Arc;

use texsyn::analysis::{Analysis, Exemplar};
use texsyn::flow::Flow;
use texsyn::gpu::advect::{quantize_velocity, AdvectOptions, Advection};
use texsyn::gpu::synth::GpuSynthesizer;
use texsyn::passes::plan::SynthPlan;
use texsyn::passes::run_cpu_frame;
use texsyn::{SynthParams, Synthesis};

use crate::common::{self, ctx};

/// An exemplar, its default analysis and a synthesizer on the shared context.
pub struct Synth {
    pub exemplar: Exemplar,
    pub analysis: Arc<Analysis>,
    pub synth: Arc<GpuSynthesizer>,
}

impl Synth {
    /// The `size` x `size` crop of the gravel exemplar (its analysis made once per test
    /// binary).
    pub fn gravel(size: u32) -> Self {
        let analysis = common::assets::gravel_crop_analysis(size);
        Self {
            exemplar: common::gravel_crop(size),
            synth: Arc::new(GpuSynthesizer::new(ctx(), analysis.clone()).unwrap()),
            analysis,
        }
    }

    /// The analysis, the synthesizer and the exemplar, for tests that drive
    /// [`Advection`] themselves.
    pub fn parts(self) -> (Arc<Analysis>, Arc<GpuSynthesizer>, Exemplar) {
        (self.analysis, self.synth, self.exemplar)
    }

    /// A shipped exemplar, `assets/NAME.png`, whole.
    pub fn asset(name: &str) -> Self {
        let exemplar = common::asset_exemplar(name);
        let analysis = Arc::new(common::assets::analysed(&exemplar));
        Self {
            synth: Arc::new(GpuSynthesizer::new(ctx(), analysis.clone()).unwrap()),
            exemplar,
            analysis,
        }
    }
}

/// An advection on the shared context, with the CPU mirror of its coordinates when made
/// by [`FrameLoop::mirrored_with_fade_room`].
pub struct FrameLoop {
    pub adv: Advection,
    /// The analysis the frames read (the mirror's, swapped with the synthesizer).
    pub analysis: Arc<Analysis>,
    /// The CPU mirror's coordinate buffer (as long as the GPU's, or longer).
    pub cpu: Option<Vec<[i32; 2]>>,
}

impl FrameLoop {
    /// Frame 0 of `opts` over `params` on the GPU.
    pub fn new(s: &Synth, params: &SynthParams, opts: AdvectOptions) -> Self {
        Self {
            adv: Advection::new(s.synth.clone(), params, opts).unwrap(),
            analysis: s.analysis.clone(),
            cpu: None,
        }
    }

    /// [`FrameLoop::new`] with the CPU mirror, its frame 0 made in a buffer with room for
    /// fade state, which the frames may turn on later (the GPU's buffer grows then).
    pub fn mirrored_with_fade_room(s: &Synth, params: &SynthParams, opts: AdvectOptions) -> Self {
        let mut l = Self::new(s, params, opts);
        let len = l.adv.plan().advect_buffer_len(true);
        l.cpu = Some(cpu_frame0(&l.analysis, l.adv.plan(), &opts, len));
        l
    }

    /// The plan of the frames.
    pub fn plan(&self) -> SynthPlan {
        self.adv.plan().clone()
    }

    /// The current frame's colours, RGBA8.
    pub fn rgba(&self) -> Vec<u8> {
        self.adv.read_rgba8().unwrap()
    }

    /// The GPU's coordinate buffer.
    pub fn coords(&self) -> Vec<[i32; 2]> {
        self.adv.read_coords().unwrap()
    }

    /// The CPU mirror's buffer.
    pub fn cpu(&self) -> &[[i32; 2]] {
        self.cpu
            .as_deref()
            .expect("a FrameLoop without its CPU mirror")
    }

    /// One frame on the GPU under velocities `v` (one per output pixel) and time step
    /// `dt`; the mirror, if any, is left behind.
    pub fn step(&mut self, v: &[[f32; 2]], dt: f32) {
        self.adv.step(v, dt).unwrap();
    }

    /// One frame on the GPU and the same frame (the advection's own schedule) on the
    /// mirror: the mirror's output.
    pub fn step_mirrored(&mut self, v: &[[f32; 2]], dt: f32) -> Synthesis {
        let schedule = self.adv.frame_schedule();
        self.adv.step(v, dt).unwrap();
        let jac = self.adv.plan().jacobians();
        let q: Vec<[i32; 2]> = v.iter().map(|&v| quantize_velocity(v, dt)).collect();
        let analysis = self.analysis.clone();
        let cpu = self
            .cpu
            .as_mut()
            .expect("a FrameLoop without its CPU mirror");
        run_cpu_frame(&analysis, &schedule, cpu, &jac, &[], &q).unwrap()
    }

    /// `frames` frames under the same velocities: `each(t, previous, current)` sees the
    /// colours of frame t - 1 and frame t (t from 1); returns the last frame's colours.
    pub fn run(
        &mut self,
        frames: u64,
        v: &[[f32; 2]],
        dt: f32,
        mut each: impl FnMut(u64, &[u8], &[u8]),
    ) -> Vec<u8> {
        let mut prev = self.rgba();
        for t in 1..=frames {
            self.step(v, dt);
            let cur = self.rgba();
            each(t, &prev, &cur);
            prev = cur;
        }
        prev
    }
}

/// Frame 0 of `plan` with `opts` on the CPU mirror, in a buffer of `len` entries (the
/// advection's coordinate buffer, or longer to hold fade state turned on later).
pub fn cpu_frame0(a: &Analysis, plan: &SynthPlan, opts: &AdvectOptions, len: u64) -> Vec<[i32; 2]> {
    let mut cpu = vec![[0i32; 2]; len as usize];
    run_cpu_frame(
        a,
        &plan.advect_first_schedule(a, opts),
        &mut cpu,
        &plan.jacobians(),
        &[],
        &[],
    );
    cpu
}

/// Advances `adv` by frame `frame` (its own options, host velocities `v`) on the GPU and
/// `cpu` by the same frame on the CPU mirror of analysis `a`; whether their coordinates
/// agree.
pub fn step_matches_cpu(
    adv: &mut Advection,
    a: &Analysis,
    frame: u64,
    cpu: &mut [[i32; 2]],
    v: &[[f32; 2]],
    dt: f32,
) -> bool {
    assert_eq!(adv.frame(), frame);
    // The advection's own schedule: after a change of parameters or analysis it first
    // makes the levels above the advected ones again.
    let schedule = adv.frame_schedule();
    adv.step(v, dt).unwrap();
    let plan = adv.plan();
    let q: Vec<[i32; 2]> = v.iter().map(|&v| quantize_velocity(v, dt)).collect();
    run_cpu_frame(a, &schedule, cpu, &plan.jacobians(), &[], &q);
    adv.read_coords().unwrap() == cpu
}

/// Synthesis parameters of a `w` x `h` output.
pub fn output(w: u32, h: u32) -> SynthParams {
    SynthParams {
        width: w,
        height: h,
        ..SynthParams::default()
    }
}

/// The velocities of a rigid vortex about the centre of a `w` x `h` output at `omega`
/// radians per frame.
pub fn centred_vortex_velocities(w: u32, h: u32, omega: f32) -> Vec<[f32; 2]> {
    Flow::Vortex {
        cx: 0.5,
        cy: 0.5,
        omega,
    }
    .sample(w, h, 0.0)
    .unwrap()
}

/// Synthesis parameters of a `w` x `h` output and the velocities of a rigid vortex about
/// its centre at `omega` radians per frame.
pub fn centred_vortex(w: u32, h: u32, omega: f32) -> (SynthParams, Vec<[f32; 2]>) {
    (output(w, h), centred_vortex_velocities(w, h, omega))
}

/// The fading tests' flow: a vortex fast enough to renew patches within a few frames.
pub const FAST_VORTEX: Flow = Flow::Vortex {
    cx: 0.5,
    cy: 0.5,
    omega: 0.06,
};

/// Frame `f`'s velocities of `flow` over a `w` x `h` output, and as the GPU quantizes them
/// (dt 1).
pub fn frame_velocities(flow: &Flow, w: u32, h: u32, f: u64) -> (Vec<[f32; 2]>, Vec<[i32; 2]>) {
    let v = flow.sample(w, h, f as f32).unwrap();
    let q = v.iter().map(|&v| quantize_velocity(v, 1.0)).collect();
    (v, q)
}

/// A caller-owned velocity buffer (`Advection::encode_step`) holding `v`.
pub fn velocity_buffer(v: &[[f32; 2]]) -> wgpu::Buffer {
    wgpu::util::DeviceExt::create_buffer_init(
        &ctx().device,
        &wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(v),
            usage: wgpu::BufferUsages::STORAGE,
        },
    )
}

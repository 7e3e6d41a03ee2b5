//! One job from validated document to result: the pipeline of the projection method
//! (build → transform → threshold → solve → metrics) and the assembly of the result.
//! Kinds and methods plug in by producing a `Solution`.

use crate::flatland::projection as flatland;
use crate::math::field::Field;
use crate::methods::compress::{self, KeptMatrix, MagnitudePicture};
use crate::methods::projection::{Dense, Discretization, Layout, System};
pub use crate::methods::solution::JobError;
use crate::methods::solution::Solution;
use crate::methods::solve;
use crate::metrics;
use crate::progress::{Cancelled, Phase, Progress};
use crate::result::*;
use crate::scene::{BasisKind, Job, Keep, Method, Reference, Rgb, SceneKind};
use crate::three_d::projection as three_d;
pub use crate::three_d::rules::Rules;
use std::collections::BTreeMap;
use std::time::Instant;

/// Everything a finished job yields apart from the images, which [`crate`] users render from
/// the fields.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub result: JobResult,
    /// B over each surface, as the images show it (`Solution::shown`); the result's
    /// numbers are its means except on elements a solid partly covers.
    pub fields: Vec<Field>,
    /// The kernel matrix magnitudes in the chosen basis (projection method).
    pub(crate) picture: Option<MagnitudePicture>,
}

/// Runs a job.
pub fn run(job: &Job, progress: &dyn Progress) -> Result<Outcome, JobError> {
    run_with(job, &Rules::DEFAULT, progress)
}

/// Runs a job with the 3D refinement's rules changed ([`Rules`]: to show what each bounds).
pub fn run_with(job: &Job, rules: &Rules, progress: &dyn Progress) -> Result<Outcome, JobError> {
    let start = Instant::now();
    let given = job.solver.resolution_given.then_some(job.solver.resolution);
    let mut sol = solve_job(
        job,
        job.solver.order,
        given,
        job.solver.keep,
        rules,
        progress,
    )?;
    let names = job.surface_names();
    let measure = surface_measures(job);
    let t = Instant::now();
    let (radiosity_error, reference) = match job.output.reference {
        None => (None, None),
        Some(Reference::Exact) => {
            let SceneKind::Fredholm(f) = &job.scene.kind else {
                unreachable!("validated: exact needs fredholm")
            };
            let exact = f.exact.as_ref().expect("validated: exact present");
            let [a, b] = f.domain;
            let (d, n) =
                metrics::l2_against(&sol.fields[0], b - a, |s| exact.eval(a + s * (b - a), 0.0));
            (Some(d / n), Some("exact".to_string()))
        }
        Some(Reference::Finer { order, resolution }) => {
            progress.report(Phase::Reference, 0.0);
            let quiet = Relabel {
                inner: progress,
                phase: Phase::Reference,
            };
            let reference = solve_job(job, order, Some(resolution), Keep::All, rules, &quiet)?;
            let (mut d, mut n) = (0.0, 0.0);
            for (i, f) in sol.fields.iter().enumerate() {
                let (di, ni) = metrics::l2_difference(f, &reference.fields[i], measure[i]);
                d += di;
                n += ni;
            }
            (
                Some(d / n),
                Some(format!("order {order}, resolution {resolution}")),
            )
        }
    };
    sol.timings.insert("reference".into(), ms(t));
    progress.report(Phase::Metrics, 0.0);
    let rho = reflectances(job);
    let energy = metrics::energy(&sol.emission, &sol.irradiance, &rho, &measure);
    let surfaces = match &job.scene.kind {
        SceneKind::ThreeD(d) if !d.parallelograms_only() => surfaces_of_patches(
            d,
            &sol.fields,
            &measure,
            job.output.grid,
            job.output.vertices,
        ),
        _ => names
            .iter()
            .zip(&sol.fields)
            .map(|(name, f)| SurfaceResult {
                name: name.clone(),
                mean: f.mean(),
                cells: f.cell_means(job.output.grid),
                vertices: None,
            })
            .collect(),
    };
    let (sorted_ranks, sorted_magnitudes) = sol.magnitudes.iter().copied().unzip();
    sol.timings.insert("total".into(), ms(start));
    let result = JobResult {
        scene: job.scene.name.clone(),
        kind: job.scene.kind.name().into(),
        solver: echo(job),
        surfaces,
        coefficients: Coefficients {
            basis_size: sol.basis_size,
            matrix_entries: sol.matrix_entries,
            kept_entries: sol.kept_entries,
            sparsity_ratio: 1.0 - sol.kept_entries as f64 / sol.matrix_entries.max(1) as f64,
            cut: sol.cut,
            sorted_magnitudes,
            sorted_ranks,
        },
        metrics: Metrics {
            kernel_relative_error: sol.kernel_error,
            kernel_pairs_left_out: sol
                .left_out
                .iter()
                .map(|&(i, j)| [names[i].clone(), names[j].clone()])
                .collect(),
            kernel_error_sampling: sol.kernel_error_sampling.clone(),
            radiosity_relative_error: radiosity_error,
            reference,
            iterations: sol.solved.iterations,
            converged: sol.solved.converged,
            final_residual: sol.solved.residual,
            residual_history: sol.solved.history.clone(),
            kernel_evaluations: sol.kernel_evaluations,
            energy,
        },
        timings_ms: sol.timings.clone(),
        hierarchical: sol.hierarchy.clone(),
        warnings: crate::warnings::geometry(job),
    };
    progress.report(Phase::Metrics, 1.0);
    Ok(Outcome {
        result,
        fields: sol.shown.unwrap_or(sol.fields),
        picture: sol.picture,
    })
}

/// The results of a 3D scene's surfaces from its patches' fields: a parallelogram's as its
/// patch's; a triangle's or a mesh's mean weighted by the triangles' areas, one cell per
/// triangle, and with `vertices` B at each position averaged over the triangles that meet
/// there (scene.md).
fn surfaces_of_patches(
    d: &crate::scene::ThreeD,
    fields: &[Field],
    area: &[f64],
    grid: usize,
    vertices: bool,
) -> Vec<SurfaceResult> {
    use crate::scene::Shape3;
    d.surfaces
        .iter()
        .map(|s| {
            let patches = s.patches.clone();
            let total: f64 = area[patches.clone()].iter().sum();
            let mut mean = [0.0; 3];
            let cells: Vec<Rgb> = patches.clone().map(|i| fields[i].mean()).collect();
            for (c, a) in cells.iter().zip(&area[patches.clone()]) {
                (0..3).for_each(|ch| mean[ch] += c[ch] * a / total);
            }
            let at_positions = match (&s.shape, vertices) {
                (Shape3::Triangle, true) => {
                    Some(vertex_values(3, &[[0, 1, 2]], &fields[patches.clone()]))
                }
                (
                    Shape3::Mesh {
                        positions,
                        triangles,
                    },
                    true,
                ) => Some(vertex_values(
                    positions.len(),
                    triangles,
                    &fields[patches.clone()],
                )),
                _ => None,
            };
            match s.shape {
                Shape3::Parallelogram => SurfaceResult {
                    name: s.name.clone(),
                    mean: fields[patches.start].mean(),
                    cells: fields[patches.start].cell_means(grid),
                    vertices: None,
                },
                _ => SurfaceResult {
                    name: s.name.clone(),
                    mean,
                    cells,
                    vertices: at_positions,
                },
            }
        })
        .collect()
}

/// B at each of `positions` points of a mesh whose triangle `i` has the field `fields[i]`: the
/// value of each triangle's polynomial at its corners ((0, 0), (1, 0), (0, 1) of its (s, t)),
/// averaged over the triangles that meet at the position (scene.md's `vertices`).
pub(crate) fn vertex_values(
    positions: usize,
    triangles: &[[usize; 3]],
    fields: &[Field],
) -> Vec<Rgb> {
    let mut sum = vec![[0.0; 3]; positions];
    let mut count = vec![0usize; positions];
    for (t, f) in triangles.iter().zip(fields) {
        let corners = [f.eval(0.0, 0.0), f.eval(1.0, 0.0), f.eval(0.0, 1.0)];
        for (&p, v) in t.iter().zip(corners) {
            (0..3).for_each(|c| sum[p][c] += v[c]);
            count[p] += 1;
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(v, &n)| v.map(|x| x / n.max(1) as f64))
        .collect()
}

/// The Galerkin system of the projection method for any kind of scene.
pub fn system(
    job: &Job,
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<System, Cancelled> {
    match &job.scene.kind {
        SceneKind::Flatland(segments) => flatland::build(segments, disc, progress),
        SceneKind::Fredholm(f) => crate::fredholm::build(f, disc, progress),
        SceneKind::ThreeD(quads) => three_d::build(quads, disc, progress),
    }
}

/// Solves the job's scene at the given order, resolution and keep rule. A resolution of `None`
/// (not in the document) is the default's for the projection method and no cap for the
/// hierarchical method in 3D, whose elements `min_element_size` sizes.
pub fn solve_job(
    job: &Job,
    order: usize,
    given: Option<usize>,
    keep: Keep,
    rules: &Rules,
    progress: &dyn Progress,
) -> Result<Solution, JobError> {
    let resolution = given.unwrap_or(job.solver.resolution);
    // a reference solve at a higher order needs at least its own default rule
    let quadrature = if order == job.solver.order {
        job.solver.quadrature
    } else {
        job.solver.quadrature.max(order + 2)
    };
    let disc = Discretization {
        order,
        cells: resolution,
        quadrature,
    };
    let settings = solve::Settings {
        iteration: job.solver.iteration,
        tolerance: job.solver.tolerance,
        max_iterations: job.solver.max_iterations,
    };
    let mut sol = match (&job.scene.kind, job.solver.method) {
        (SceneKind::Fredholm(_), Method::Hierarchical) => {
            return Err(JobError::Unsupported {
                method: "hierarchical",
                scene: "fredholm",
            })
        }
        (SceneKind::Flatland(segments), Method::Hierarchical) => crate::flatland::hierarchy::solve(
            segments,
            order,
            resolution,
            crate::flatland::hierarchy::Tuning {
                quadrature,
                epsilon: job.solver.epsilon,
                coefficients: job.output.coefficients,
            },
            settings,
            progress,
        )?,
        (SceneKind::ThreeD(_), Method::Hierarchical) => {
            crate::three_d::hierarchy::solve(job, order, given, rules, progress)?
        }
        (_, Method::Projection) => {
            let t = Instant::now();
            let system = system(job, disc, progress)?;
            let build_ms = ms(t);
            let mut sol = projection_solve(system, job, keep, progress)?;
            sol.timings.insert("projection".into(), build_ms);
            sol
        }
    };
    let t = Instant::now();
    let (err, left_out) = match &job.scene.kind {
        SceneKind::ThreeD(quads) => kernel_error_3d(quads, disc, &sol, progress)?,
        _ => kernel_error_1d(job, disc, &sol, progress)?,
    };
    sol.kernel_error = err;
    sol.left_out = left_out;
    sol.timings.insert("metrics".into(), ms(t));
    Ok(sol)
}

/// Transform, threshold and solve a system; B, E and H as fields.
fn projection_solve(
    mut system: System,
    job: &Job,
    keep: Keep,
    progress: &dyn Progress,
) -> Result<Solution, JobError> {
    let mut timings = BTreeMap::new();
    let wavelet = job.solver.basis == BasisKind::Wavelet;
    let layout = system.layout;
    let t = Instant::now();
    if wavelet {
        compress::to_wavelet(&mut system, progress)?;
    }
    timings.insert("transform".into(), ms(t));
    let t = Instant::now();
    progress.check()?;
    let ranking = compress::Ranking::new(&system.matrix.data, progress)?;
    let ranks = compress::sample_ranks(ranking.len(), job.output.coefficients);
    let magnitudes = ranks
        .iter()
        .copied()
        .zip(
            ranking
                .locate(&system.matrix.data, &ranks)
                .into_iter()
                .map(|x| x.0),
        )
        .collect();
    let basis_size = system.size();
    let matrix_entries = basis_size * basis_size;
    let matrix = std::mem::replace(&mut system.matrix, Dense::zeros(0));
    let (kept, kept_entries, cut, squares) =
        compress::keep_entries(matrix, keep, &ranking, layout.len());
    let picture = picture_of(&kept, cut);
    timings.insert("threshold".into(), ms(t));
    let t = Instant::now();
    let rho: Vec<Rgb> = (0..basis_size)
        .map(|i| system.reflectance[system.surface_of(i)])
        .collect();
    let settings = solve::Settings {
        iteration: job.solver.iteration,
        tolerance: job.solver.tolerance,
        max_iterations: job.solver.max_iterations,
    };
    let solved = solve::solve(kept.operator(), &rho, &system.emission, settings, progress)?;
    timings.insert("solve".into(), ms(t));
    let mut b = solved.b.clone();
    let mut h = solve::multiply(kept.operator(), &solved.b);
    drop(kept);
    let mut e = system.emission.clone();
    if wavelet {
        for v in [&mut b, &mut h, &mut e] {
            compress::inverse_rgb(layout, v);
        }
    }
    let order = layout.k() - 1;
    let fields = fields_from_scaling(layout, order, &system.measure, &b);
    let irradiance = fields_from_scaling(layout, order, &system.measure, &h);
    let emission = fields_from_scaling(layout, order, &system.measure, &e);
    let mut sol = Solution {
        fields,
        shown: None,
        emission,
        irradiance,
        basis_size,
        matrix_entries,
        kept_entries,
        cut,
        magnitudes,
        picture: Some(picture),
        solved,
        kernel_error: None,
        kernel_error_sampling: None,
        left_out: system.touching.clone(),
        hierarchy: None,
        timings,
        kept_squares: Vec::new(),
        kernel_evaluations: system.kernel_evaluations,
    };
    sol.kept_squares = squares;
    Ok(sol)
}

/// The sparsity picture of what was kept (dropped entries are zero in it).
fn picture_of(kept: &KeptMatrix, cut: f64) -> MagnitudePicture {
    match kept {
        KeptMatrix::Dense(d) => compress::picture(d, 512, cut),
        KeptMatrix::Sparse(c) => compress::picture_sparse(c, 512, cut),
    }
}

/// Eq. (5), and the pairs of surfaces it left out.
type KernelError = (Option<f64>, Vec<(usize, usize)>);

/// Eq. (5) for flatland and fredholm.
fn kernel_error_1d(
    job: &Job,
    disc: Discretization,
    sol: &Solution,
    progress: &dyn Progress,
) -> Result<KernelError, Cancelled> {
    progress.check()?;
    let squares = &sol.kept_squares;
    // ∫∫K² with three more Gauss points per cell than the projection, on at most 64 cells
    // per surface (K² is smooth away from touching pairs, and near pairs are refined anyway)
    let fine = Discretization {
        order: 0,
        cells: disc.cells.min(64),
        quadrature: disc.quadrature + 3,
    };
    match &job.scene.kind {
        SceneKind::Flatland(segments) => {
            let geo = flatland::Geometry::new(segments);
            let touching = geo.touching();
            let touch = |i: usize, j: usize| touching.contains(&(i.min(j), i.max(j)));
            let k2 = flatland::kernel_squares(&geo, fine, touch);
            let s = segments.len();
            let mut kept = 0.0;
            for i in 0..s {
                for j in 0..s {
                    if i != j && !touch(i, j) {
                        kept += squares[i * s + j];
                    }
                }
            }
            let total: f64 = k2.iter().sum();
            Ok((metrics::kernel_relative_error(total, kept), touching))
        }
        SceneKind::Fredholm(f) => {
            let [a, b] = f.domain;
            let n = fine.cells;
            let h = (b - a) / n as f64;
            let rule = crate::math::quadrature::Rule::gauss(fine.quadrature + 2);
            let mut total = 0.0;
            for ca in 0..n {
                for cb in 0..n {
                    let sa = [a + ca as f64 * h, a + (ca + 1) as f64 * h];
                    let sb = [a + cb as f64 * h, a + (cb + 1) as f64 * h];
                    total += rule.integrate2(sa, sb, |x, y| f.kernel.eval(x, y).powi(2));
                }
            }
            Ok((
                metrics::kernel_relative_error(total, squares.iter().sum()),
                vec![],
            ))
        }
        SceneKind::ThreeD(_) => unreachable!("3d scenes take kernel_error_3d"),
    }
}

/// Eq. (5) and the surface pairs it left out.
type KernelError3d = (Option<f64>, Vec<(usize, usize)>);

/// Eq. (5) for 3D scenes over the pairs of surfaces that do not touch.
fn kernel_error_3d(
    quads: &[crate::scene::Quad],
    disc: Discretization,
    sol: &Solution,
    progress: &dyn Progress,
) -> Result<KernelError3d, Cancelled> {
    progress.check()?;
    // eq. (5) over every pair of patches would cost as much as the solve on a mesh (and its
    // cells are the parallelograms'), and s² quadratures on many surfaces: there the
    // hierarchy has sampled it
    if sol.kernel_error_sampling.is_some() {
        return Ok((sol.kernel_error, sol.left_out.clone()));
    }
    let geo = three_d::Geometry::new(quads);
    let touching = geo.touching();
    let touch = |i: usize, j: usize| touching.contains(&(i.min(j), i.max(j)));
    let k2 = three_d::kernel_squares(
        &geo,
        disc.cells.clamp(2, 4),
        disc.quadrature + 1,
        touch,
        progress,
    )?;
    let s = quads.len();
    let mut kept = 0.0;
    for i in 0..s {
        for j in 0..s {
            if i != j && !touch(i, j) {
                kept += sol.kept_squares[i * s + j];
            }
        }
    }
    let total: f64 = k2.iter().sum();
    Ok((metrics::kernel_relative_error(total, kept), touching))
}

/// Per-surface fields from scaling-basis coefficients: N = φ_p(ŝ)[φ_q(t̂)] / √(h^d · measure).
fn fields_from_scaling(
    layout: Layout,
    order: usize,
    measure: &[f64],
    coeffs: &[Rgb],
) -> Vec<Field> {
    let per = layout.len();
    coeffs
        .chunks(per)
        .zip(measure)
        .map(|(c, &m)| {
            let h = 1.0 / layout.cells() as f64;
            match layout {
                Layout::Line { cells, .. } => {
                    let f = 1.0 / (h * m).sqrt();
                    let local: Vec<Rgb> = c.iter().map(|v| v.map(|x| x * f)).collect();
                    Field::uniform_line(order, cells, &local)
                }
                Layout::Square { cells, .. } => {
                    let f = 1.0 / (h * h * m).sqrt();
                    let local: Vec<Rgb> = c.iter().map(|v| v.map(|x| x * f)).collect();
                    Field::uniform_square(order, cells, &local)
                }
            }
        })
        .collect()
}

/// Length or area of every surface (the domain's length for fredholm).
pub fn surface_measures(job: &Job) -> Vec<f64> {
    match &job.scene.kind {
        SceneKind::Flatland(s) => s
            .iter()
            .map(|s| (s.b[0] - s.a[0]).hypot(s.b[1] - s.a[1]))
            .collect(),
        SceneKind::ThreeD(q) => q
            .iter()
            .map(|q| {
                let c = &q.corners;
                let e1 = [c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]];
                let e3 = [c[3][0] - c[0][0], c[3][1] - c[0][1], c[3][2] - c[0][2]];
                let x = [
                    e1[1] * e3[2] - e1[2] * e3[1],
                    e1[2] * e3[0] - e1[0] * e3[2],
                    e1[0] * e3[1] - e1[1] * e3[0],
                ];
                let a = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                if q.triangle {
                    0.5 * a
                } else {
                    a
                }
            })
            .collect(),
        SceneKind::Fredholm(f) => vec![f.domain[1] - f.domain[0]],
    }
}

fn reflectances(job: &Job) -> Vec<Rgb> {
    match &job.scene.kind {
        SceneKind::Flatland(s) => s.iter().map(|s| s.material.reflectance).collect(),
        SceneKind::ThreeD(q) => q.iter().map(|q| q.material.reflectance).collect(),
        SceneKind::Fredholm(_) => vec![[1.0; 3]],
    }
}

fn echo(job: &Job) -> SolverEcho {
    let s = &job.solver;
    SolverEcho {
        method: match s.method {
            Method::Projection => "projection",
            Method::Hierarchical => "hierarchical",
        }
        .into(),
        basis: match s.basis {
            BasisKind::Scaling => "scaling",
            BasisKind::Wavelet => "wavelet",
        }
        .into(),
        order: s.order,
        resolution: s.resolution,
        keep: match s.keep {
            Keep::All => serde_json::json!("all"),
            Keep::Top(n) => serde_json::json!({ "top": n }),
            Keep::Fraction(f) => serde_json::json!({ "fraction": f }),
            Keep::Threshold(t) => serde_json::json!({ "threshold": t }),
        },
        iteration: match s.iteration {
            crate::scene::Iteration::Jacobi => "jacobi",
            crate::scene::Iteration::GaussSeidel => "gauss-seidel",
        }
        .into(),
        tolerance: s.tolerance,
        max_iterations: s.max_iterations,
        quadrature: s.quadrature,
        epsilon: s.epsilon,
    }
}

fn ms(t: Instant) -> f64 {
    (t.elapsed().as_secs_f64() * 1e6).round() / 1e3
}

/// Forwards progress under another phase (the reference solve reports as `reference`).
struct Relabel<'a> {
    inner: &'a dyn Progress,
    phase: Phase,
}

impl Progress for Relabel<'_> {
    fn report(&self, _phase: Phase, fraction: f64) {
        self.inner.report(self.phase, fraction);
    }
    fn cancelled(&self) -> bool {
        self.inner.cancelled()
    }
}

//! Hierarchical wavelet radiosity (Gortler, Schröder, Cohen and Hanrahan, "Wavelet Radiosity",
//! SIGGRAPH 1993; Hanrahan, Salzman and Aupperle, "A Rapid Hierarchical Radiosity Algorithm",
//! SIGGRAPH 1991) for 3D scenes.
//!
//! Instead of the whole Galerkin matrix of eq. (11), only the interactions that the refinement
//! oracle ([`refine`]) asks for are built, as links between elements of per-surface quadtrees
//! ([`tree`]) at whatever levels carry the transfer to within ε. A mesh is refined as one
//! surface: its triangles are the leaves of a cluster tree ([`crate::three_d::cluster`]), a
//! subtree of one tree over all the meshes, whose root is paired with itself and with each
//! surface of one patch where the refinement starts; the oracle of [`clustered`] splits
//! clusters down to the triangles' elements where it asks, and links that stay between
//! clusters carry the oriented point-to-point transfer. Solving alternates
//!
//! 1. gather: H_R = Σ_links T_RS B_S over each element's links;
//! 2. push-pull: H pushed down to the leaves, B = E + ρ H there, B pulled back up;
//!
//! (a Jacobi sweep of B = E + ρ K B in the multiresolution basis; with the document's
//! `"gauss-seidel"`, both steps patch by patch, each patch's gather reading the B that the
//! patches before it got in the same sweep) to the solver's tolerance,
//! then re-refines the links with the new B ("BF refinement", with the shadow budget of
//! [`shadows`] on the sum of the partly visible links' errors at each leaf) until no link
//! changes. Once the changes of the sweeps show one dominant mode, B jumps to the sum of their
//! geometric series ([`crate::methods::extrapolation`]); the sweeps after it go on to the same
//! fixed point.
//!
//! Where a solid stands on a surface ([`crate::three_d::cover`]), the elements across the outline of
//! its foot are split to the finest level before any link is made, and every partly covered
//! element holds the polynomial of its exposed part: links into it deliver the masked moments
//! ∫ χ φ H (their blocks weighted by its masked Gram matrices and the visible fraction of its
//! exposed part), push-pull turns them into that polynomial by G⁺, and the numbers reported
//! count the covered part as B = E.

mod clustered;
mod kernel_error;
mod links;
mod refine;
mod shadows;
mod sizing;
mod tolerance;
mod tree;

use crate::math::basis::Filters;
use crate::math::field::{Field, Leaf};
use crate::math::triangle::TriangleBasis;
use crate::methods::extrapolation::Lyusternik;
use crate::methods::solution::{JobError, Solution};
use crate::methods::solve::Solved;
use crate::progress::{Cancelled, Phase, Progress};
use crate::result::HierarchyStats;
use crate::scene::{Job, Quad, Rgb, SceneKind};
use crate::three_d::cluster::{is_cluster, Clusters};
use crate::three_d::cover::{Exposure, Mask, Partial, SUB};
use crate::three_d::geometry::Piece;
use crate::three_d::projection::{piece_emission, Geometry};
use crate::three_d::rules::Rules;
use crate::three_d::transfer::Accuracy;
use crate::three_d::visibility::Seen;
use links::Links;
use rayon::prelude::*;
use refine::{Factors, Link};
use sizing::{Sizing, MAX_LEVEL};
use std::collections::BTreeMap;
use std::time::Instant;
use tree::{pull, push, Element, NONE};

/// The most coefficients of an element (k² for the highest order).
const MAX_KK: usize = crate::three_d::transfer::MAX_K * crate::three_d::transfer::MAX_K;

/// Refinement passes after the first solve, at most.
const MAX_PASSES: usize = 6;

/// The residual to which the solves between refinement passes go.
const ROUGH: f64 = 1e-3;

/// The elements, links and settings of one hierarchical solve.
struct Hierarchy<'g> {
    geo: &'g Geometry,
    quads: &'g [Quad],
    filters: &'static Filters,
    /// The two-scale relation of triangle patches' elements.
    tri_basis: &'static TriangleBasis,
    k: usize,
    /// The finest level of each surface's quadtree away from narrow gaps, by [`sizing`].
    levels: Vec<u32>,
    /// The finest level anywhere on each surface: of its fields' cells.
    deepest: Vec<u32>,
    sizing: Sizing,
    /// The constants of the rules beyond the oracle's estimate.
    rules: Rules,
    threshold: f64,
    /// The typical reflected radiosity per channel (area-weighted mean over the non-emitting
    /// surfaces) of the last solve; 0 before the first ([`tolerance`]).
    typical: [f64; 3],
    /// Whether the links are judged with a solve's B (after the first solve): B, not only
    /// E, then weighs the rays and the receiving members' visible fractions. Not the
    /// typical B being positive: in a furnace every surface emits, and there is none.
    solved: bool,
    /// Largest channel of ρ per surface.
    rho: Vec<f64>,
    /// The weights w_RS of the oracle for inter-reflected light, per pair of document
    /// surfaces ([`tolerance`]).
    indirect: tolerance::Weights,
    accuracy: Accuracy,
    /// The grid on which pairs of pieces are compared for congruence: 2⁻³² of the scene.
    unit: f64,
    /// Pairs accepted without a link because none of their rays got through, with their
    /// oracle factor: BF refinement looks at them again as the sources brighten.
    hidden: Vec<(u32, u32, Factors)>,
    /// Kernel evaluations spent on link blocks so far.
    evaluations: std::sync::atomic::AtomicU64,
    /// The covered part of each surface that a solid stands on ([`crate::three_d::cover`]).
    masks: Vec<Option<Mask>>,
    /// The lines where other surfaces stand on each surface ([`crate::three_d::cover::contacts`]).
    contacts: Vec<Vec<[[f64; 2]; 2]>>,
    elements: Vec<Element>,
    links: Links,
    /// The cluster tree over the patches, where the refinement starts ([`clustered`]).
    clusters: Clusters,
    /// The patches under the cluster tree, in its order ([`clustered::Member`]).
    members: Vec<clustered::Member>,
    /// Links with a cluster at one end or both.
    cluster_links: Vec<clustered::ClusterLink>,
    /// The light of the clusters and patches, refilled in each sweep of a pass in the same
    /// memory.
    lights: clustered::Lights,
    /// Cluster pairs accepted without a link because none of their rays got through, with
    /// the oracle's factor for what the rays may have missed.
    hidden_clusters: Vec<(u32, u32, f64)>,
    /// Per cluster, what the oracle needs of its members, from the last solve.
    cluster_state: Vec<clustered::State>,
    rays: u64,
    refinements: usize,
    /// What the refinement may hold.
    budget: Budget,
    /// Set when the refinement stopped at a bound of its `budget`.
    too_large: Option<Overrun>,
    /// The document's `iteration`: Gauss–Seidel sweeps ([`Hierarchy::sweep`]) rather than
    /// Jacobi.
    gauss_seidel: bool,
}

impl<'g> Hierarchy<'g> {
    /// Roots for every surface, with E projected, split down to the finest level along the
    /// outline of any covered part; no links yet.
    fn new(
        geo: &'g Geometry,
        quads: &'g [Quad],
        order: usize,
        sizing: Sizing,
        epsilon: f64,
        rules: &Rules,
    ) -> Hierarchy<'g> {
        let k = order + 1;
        let emax = quads
            .iter()
            .flat_map(|q| q.material.emission)
            .fold(0.0, f64::max);
        let levels: Vec<u32> = geo.quads.iter().map(|q| sizing.finest_level(q)).collect();
        let deepest: Vec<u32> = geo
            .quads
            .iter()
            .enumerate()
            .map(|(i, q)| sizing.deepest_level(i, q))
            .collect();
        let groups = surface_groups(quads);
        let contacts = crate::three_d::cover::scene_contacts(&geo.bvh);
        let masks = Mask::of_scene(&geo.bvh, &contacts, &groups, rules, |i| 1 << deepest[i]);
        let elements: Vec<Element> = quads
            .iter()
            .enumerate()
            .map(|(i, q)| {
                let piece = Piece::whole(i);
                let area = geo.quads[i].area;
                let mut e = vec![[0.0; 3]; k * k];
                piece_emission(q, area, piece, k, &mut e);
                Element {
                    peak: refine::peak_emission(q, piece),
                    piece,
                    level: 0,
                    cell: [0, 0],
                    children: NONE,
                    area,
                    b: e.clone(),
                    e,
                    h: vec![[0.0; 3]; k * k],
                    detail: 0.0,
                    exposure: masks[i].as_ref().map_or(Exposure::Open, |m| {
                        m.exposure_of(&piece, geo.quads[i].tri, k)
                    }),
                }
            })
            .collect();
        let mut clusters = Clusters::new(&geo.quads, &groups);
        // a patch wholly covered by a solid resting on it takes no part in the transfer,
        // unless it emits (a covered part keeps B = E)
        clusters.weigh(&geo.quads, |p| f64::from(elements[p].sends()));
        let members = clustered::members(&clusters, &geo.quads);
        let mut h = Hierarchy {
            geo,
            quads,
            filters: Filters::of_order(order),
            tri_basis: TriangleBasis::of_order(order),
            k,
            rules: *rules,
            levels,
            deepest,
            sizing,
            threshold: epsilon * emax,
            typical: [0.0; 3],
            solved: false,
            indirect: tolerance::indirect_weights(geo, quads, &groups),
            rho: quads
                .iter()
                .map(|q| q.material.reflectance.iter().copied().fold(0.0, f64::max))
                .collect(),
            accuracy: Accuracy::coarse(order + 2),
            unit: geo.quads.iter().map(|q| q.diameter()).fold(0.0, f64::max) * (-32f64).exp2(),
            evaluations: std::sync::atomic::AtomicU64::new(0),
            hidden: Vec::new(),
            masks,
            contacts,
            elements,
            links: Links::new(k.pow(4)),
            clusters,
            members,
            cluster_links: Vec::new(),
            lights: clustered::Lights::default(),
            hidden_clusters: Vec::new(),
            cluster_state: Vec::new(),
            rays: 0,
            refinements: 0,
            budget: Budget::of_order(order),
            too_large: None,
            gauss_seidel: false,
        };
        // an element across the outline keeps one polynomial on its exposed part, which the
        // finest level confines to a strip along it; likewise an element across the edge of
        // an emission region, whose polynomial would otherwise spread the light over it (and
        // below zero next to it)
        let mut open: Vec<u32> = (0..quads.len() as u32).collect();
        while let Some(e) = open.pop() {
            let el = &h.elements[e as usize];
            let straddles = straddles_emission(&quads[el.piece.surface], el.piece);
            if (straddles || matches!(el.exposure, Exposure::Partial(_))) && el.level < h.finest(e)
            {
                let first = h.split(e);
                open.extend(first..first + 4);
            }
        }
        h
    }

    /// The finest level element `e` may be split to: its surface's, or deeper where it lies
    /// across a narrow gap ([`Sizing::level_at`]).
    fn finest(&self, e: u32) -> u32 {
        let piece = self.elements[e as usize].piece;
        self.sizing.level_at(
            piece.surface,
            &self.geo.quads[piece.surface],
            self.levels[piece.surface],
            || piece.corners(&self.geo.quads),
        )
    }

    /// Links the scene to itself, refined against the current B: every ordered pair of the
    /// cluster tree's starts ([`crate::three_d::cluster::Clusters::starts`]: the surfaces of
    /// one patch and the meshes' root; the root also with itself), two patches only when they
    /// face each other.
    fn link_all(&mut self, progress: &dyn Progress) -> Result<(), Cancelled> {
        self.cluster_state = self.measure_clusters();
        self.weigh_light();
        let starts = &self.clusters.starts;
        let mut pairs = Vec::new();
        for &a in starts {
            for &b in starts {
                let patches = !is_cluster(a) && !is_cluster(b);
                if (patches && self.geo.facing(a as usize, b as usize))
                    || (!patches && (a != b || is_cluster(a)))
                {
                    pairs.push((a, b));
                }
            }
        }
        let mut pending = Vec::new();
        self.refine_all(pairs, 0, &mut pending, progress)?;
        let mut links = Links::new(self.k.pow(4));
        self.make_links(pending, &mut links, progress)?;
        self.links = links;
        self.links.sort();
        Ok(())
    }

    /// Whether an accepted pair now carries more than the threshold allows (its source
    /// brightened or turned out uneven) and can still be refined.
    fn outgrown(&self, r: u32, s: u32, x: Factors) -> bool {
        let (kernel, detail) = self.error(r, s, x);
        // the oracle's share for a receiver along a contact line ([`Rules::contact_share`])
        let contact = self.splittable(r) && x.contact;
        let limit = if contact {
            self.rules.contact_share * self.tolerance(r)
        } else {
            self.tolerance(r)
        };
        self.splits(r, s, kernel, detail, limit).is_some()
    }

    /// Sets every element's `detail` from the leaves' B; returns Σ over the leaves below
    /// `e` of their squared coefficients per channel (Parseval: the orthonormal bases make
    /// ‖B − P_e B‖² on e that sum minus ‖b_e‖²).
    fn measure_detail(&mut self, e: u32) -> [f64; 3] {
        let el = &self.elements[e as usize];
        // on a partly covered element, the norm over its exposed part, bᵀ G b ([`cover`]):
        // the fit there is the orthogonal projection for that inner product
        let own = match &el.exposure {
            Exposure::Open => el.b.iter().fold([0.0; 3], |a, c| {
                [a[0] + c[0] * c[0], a[1] + c[1] * c[1], a[2] + c[2] * c[2]]
            }),
            Exposure::Covered => [0.0; 3],
            Exposure::Partial(p) => {
                let mut g = vec![[0.0; 3]; el.b.len()];
                Partial::apply(&p.gram, &el.b, &mut g);
                el.b.iter().zip(&g).fold([0.0; 3], |a, (b, g)| {
                    [a[0] + b[0] * g[0], a[1] + b[1] * g[1], a[2] + b[2] * g[2]]
                })
            }
        };
        if el.is_leaf() {
            self.elements[e as usize].detail = 0.0;
            return own;
        }
        let first = el.children;
        let mut sum = [0.0; 3];
        for i in 0..4 {
            let c = self.measure_detail(first + i);
            (0..3).for_each(|ch| sum[ch] += c[ch]);
        }
        let el = &mut self.elements[e as usize];
        let worst = (0..3).map(|ch| sum[ch] - own[ch]).fold(0.0, f64::max);
        el.detail = (worst / el.area).sqrt();
        sum
    }

    /// Whether B is known: a solve has been made and the links are being judged again.
    fn b_known(&self) -> bool {
        self.solved
    }

    /// Re-evaluates every link with the current B; returns how many were refined.
    fn rerefine(&mut self, progress: &dyn Progress) -> Result<usize, Cancelled> {
        // the cluster links were judged before B was known, their sources' points drawn by
        // area where they emit nothing rather than by the light they send
        // ([`Hierarchy::cluster_visibility`]): every one is judged again
        let unlit = !self.b_known();
        self.solved = true;
        // the sweeps' light (100 MB for 10⁵ triangles) is let go while the refinement runs
        self.lights = clustered::Lights::default();
        self.typical = self.typical_radiosity();
        for root in 0..self.quads.len() {
            self.measure_detail(root as u32);
        }
        // each list is filtered where it is: a second copy of 7 M links was a sixth of the
        // peak memory of a 10⁵-triangle job
        let mut keep = std::mem::take(&mut self.links);
        let mut again = Vec::new();
        // the shadow budget ([`shadows`]): partly visible links whose smears add up over a
        // leaf's tolerance give way to links into their receivers' children
        let marked = self.over_shadow_budget(&keep);
        let mut at = 0;
        let shadowed = keep.extract_if(|_| {
            at += 1;
            marked[at - 1]
        });
        drop(marked);
        for l in shadowed.ends() {
            let first = self.split(l.recv);
            again.extend((first..first + 4).map(|c| (c, l.src)));
        }
        let shadowed = shadowed.len();
        let outgrown = keep.extract_if(|l| self.outgrown(l.recv, l.src, l.factors));
        again.extend(outgrown.ends().iter().map(|l| (l.recv, l.src)));
        let lit = self.relight(&mut keep);
        let mut blocks: std::collections::HashMap<(u32, u32), usize> = outgrown
            .ends()
            .iter()
            .enumerate()
            .map(|(i, l)| ((l.recv, l.src), i))
            .collect();
        let mut reopened = 0;
        let mut hidden = std::mem::take(&mut self.hidden);
        hidden.retain(|&(r, s, x)| {
            let open = self.outgrown(r, s, x);
            if open {
                again.push((r, s));
                reopened += 1;
            }
            !open
        });
        self.hidden = hidden;
        // links with a cluster at an end, and hidden cluster pairs: judged again afresh
        self.cluster_state = self.measure_clusters();
        self.weigh_light();
        let mut cluster_links = std::mem::take(&mut self.cluster_links);
        cluster_links.retain(|l| {
            let open = unlit || self.cluster_outgrown(l.recv, l.src, l.smooth, l.sampled);
            if open {
                again.push((l.recv, l.src));
                reopened += 1;
            }
            !open
        });
        self.cluster_links = cluster_links;
        let mut hidden_clusters = std::mem::take(&mut self.hidden_clusters);
        hidden_clusters.retain(|&(r, s, smooth)| {
            let open = self.cluster_outgrown(r, s, smooth, smooth);
            if open {
                again.push((r, s));
                reopened += 1;
            }
            !open
        });
        self.hidden_clusters = hidden_clusters;
        let mut pending = Vec::new();
        self.refine_all(again, keep.len(), &mut pending, progress)?;
        // a pair may come back unrefined (its estimate changed): keep its block
        let mut refined = blocks.len() + reopened + shadowed;
        pending.retain(|p| match blocks.remove(&(p.0, p.1)) {
            Some(i) => {
                refined -= 1;
                keep.push(outgrown.ends()[i], outgrown.block(i));
                false
            }
            None => true,
        });
        drop(outgrown);
        pending.extend(lit);
        self.make_links(pending, &mut keep, progress)?;
        self.links = keep;
        self.links.sort();
        Ok(refined)
    }

    /// Takes the partly visible links made before B was known out of `links`: each gets
    /// its visible fraction again from its own grid of fresh rays, as the share of the light
    /// ([`refine::Factors::unlit`]), and is returned to be linked with it (or kept as hidden
    /// when none of those rays gets through).
    fn relight(&mut self, links: &mut Links) -> Vec<(u32, u32, Factors, Seen)> {
        let unlit = links.extract_if(|l| l.factors.unlit.is_some());
        let relit: Vec<_> = unlit
            .ends()
            .par_iter()
            .map(|l| {
                let (mut x, mut rays) = (l.factors, 0);
                let n = x.unlit.take().map_or(0, usize::from);
                let v = self.share_of_light(l.recv, l.src, n, None, &mut rays);
                (l.recv, l.src, x, v, rays)
            })
            .collect();
        let mut lit = Vec::with_capacity(relit.len());
        for (r, s, x, v, rays) in relit {
            self.rays += rays;
            if v.whole > 0.0 {
                lit.push((r, s, x, v));
            } else {
                self.hidden.push((r, s, x));
            }
        }
        lit
    }

    /// One Jacobi sweep: gather over the links, then push-pull. Returns the relative change
    /// of B over the leaves.
    fn sweep(&mut self) -> f64 {
        if self.gauss_seidel {
            return self.sweep_gauss_seidel();
        }
        let kk = self.k * self.k;
        // gather, receivers in parallel, each receiver's links in a fixed order
        // every element's B side by side: the gather reads them in no particular order
        let mut all_b: Vec<Rgb> = self
            .elements
            .iter()
            .flat_map(|e| e.b.iter().copied())
            .collect();
        // a partly covered source sends what its exposed part determines ([`tree::Element::sent`])
        for (e, el) in self.elements.iter().enumerate() {
            if matches!(el.exposure, Exposure::Partial(_)) {
                el.sent(&mut all_b[e * kk..(e + 1) * kk]);
            }
        }
        let gathered: Vec<(u32, Vec<Rgb>)> = self
            .receiver_runs()
            .into_par_iter()
            .map(|(r, run)| {
                let mut h = vec![[0.0; 3]; kk];
                for (l, block) in self.links.run(run) {
                    let b = &all_b[l.src as usize * kk..(l.src as usize + 1) * kk];
                    gather(&mut h, block, b);
                }
                (r, h)
            })
            .collect();
        for e in &mut self.elements {
            e.h.iter_mut().for_each(|v| *v = [0.0; 3]);
        }
        for (r, h) in gathered {
            self.elements[r as usize].h = h;
        }
        self.gather_clusters();
        let mut change = 0.0;
        let mut norm = 0.0;
        for root in 0..self.quads.len() {
            let down = vec![[0.0; 3]; kk];
            self.push_pull(root as u32, &down, &mut change, &mut norm);
        }
        if norm > 0.0 {
            (change / norm).sqrt()
        } else {
            0.0
        }
    }

    /// Every element's B, one after another, into `x`.
    fn coefficients(&self, x: &mut Vec<f64>) {
        x.clear();
        x.extend(self.elements.iter().flat_map(|e| e.b.iter().flatten()));
    }

    /// Sets every element's B from `x`, as [`Hierarchy::coefficients`] lists them.
    fn set_coefficients(&mut self, x: &[f64]) {
        for (b, v) in self
            .elements
            .iter_mut()
            .flat_map(|e| e.b.iter_mut())
            .zip(x.chunks_exact(3))
        {
            b.copy_from_slice(v);
        }
    }

    /// Each receiver with its run of links (the links are sorted by receiver).
    fn receiver_runs(&self) -> Vec<(u32, std::ops::Range<usize>)> {
        let links = self.links.ends();
        let mut runs = Vec::new();
        let mut start = 0;
        for i in 1..=links.len() {
            if i == links.len() || links[i].recv != links[start].recv {
                runs.push((links[start].recv, start..i));
                start = i;
            }
        }
        runs
    }

    /// One block Gauss–Seidel sweep, a patch at a time in their order: each element of the
    /// patch gathers over its links from the sources' B as it is now (the patches before it
    /// already swept), then the patch is pushed and pulled. The links with a cluster at an end
    /// deliver once, from B at the start of the sweep: their sources are sums over many
    /// patches ([`clustered`]). Returns the relative change of B, as [`Hierarchy::sweep`].
    fn sweep_gauss_seidel(&mut self) -> f64 {
        let kk = self.k * self.k;
        for e in &mut self.elements {
            e.h.iter_mut().for_each(|v| *v = [0.0; 3]);
        }
        self.gather_clusters();
        // each element's run of links
        let mut runs = vec![0..0; self.elements.len()];
        for (r, run) in self.receiver_runs() {
            runs[r as usize] = run;
        }
        let (mut change, mut norm) = (0.0, 0.0);
        let mut tree = Vec::new();
        for root in 0..self.quads.len() as u32 {
            tree.clear();
            let mut open = vec![root];
            while let Some(e) = open.pop() {
                if !runs[e as usize].is_empty() {
                    tree.push(e);
                }
                let first = self.elements[e as usize].children;
                if first != NONE {
                    open.extend(first..first + 4);
                }
            }
            let this = &*self;
            let gathered: Vec<Vec<Rgb>> = tree
                .par_iter()
                .with_min_len(16)
                .map(|&r| {
                    let mut h = this.elements[r as usize].h.clone();
                    for (l, block) in this.links.run(runs[r as usize].clone()) {
                        let src = &this.elements[l.src as usize];
                        if matches!(src.exposure, Exposure::Partial(_)) {
                            let mut sent = [[0.0; 3]; MAX_KK];
                            src.sent(&mut sent[..kk]);
                            gather(&mut h, block, &sent[..kk]);
                        } else {
                            gather(&mut h, block, &src.b);
                        }
                    }
                    h
                })
                .collect();
            for (&r, h) in tree.iter().zip(gathered) {
                self.elements[r as usize].h = h;
            }
            let down = vec![[0.0; 3]; kk];
            self.push_pull(root, &down, &mut change, &mut norm);
        }
        if norm > 0.0 {
            (change / norm).sqrt()
        } else {
            0.0
        }
    }

    /// Pushes `down` (H from the ancestors, in e's basis) to the leaves and pulls B back up.
    /// The coefficient vectors of the recursion live on the stack: a sweep visits every
    /// element, and one allocation each would cost as much as the arithmetic.
    fn push_pull(&mut self, e: u32, down: &[Rgb], change: &mut f64, norm: &mut f64) {
        let kk = self.k * self.k;
        let mut total = [[0.0; 3]; MAX_KK];
        let el = &self.elements[e as usize];
        // H of the links into e, as the polynomial of its exposed part (a covered element
        // receives nothing), plus H of the ancestors'
        match &el.exposure {
            Exposure::Open => total[..kk].copy_from_slice(&el.h),
            Exposure::Covered => {}
            Exposure::Partial(p) => Partial::apply(&p.inverse, &el.h, &mut total[..kk]),
        }
        if el.exposure != Exposure::Covered {
            for i in 0..kk {
                for c in 0..3 {
                    total[i][c] += down[i][c];
                }
            }
        }
        if el.is_leaf() {
            let rho = self.quads[el.piece.surface].material.reflectance;
            let el = &mut self.elements[e as usize];
            for i in 0..kk {
                for c in 0..3 {
                    let b = el.e[i][c] + rho[c] * total[i][c];
                    *change += (b - el.b[i][c]).powi(2);
                    *norm += b * b;
                    el.b[i][c] = b;
                }
            }
            // the leaf keeps its total irradiance in h for the energy balance
            el.h.copy_from_slice(&total[..kk]);
            return;
        }
        let first = el.children;
        let mut b = [[0.0; 3]; MAX_KK];
        let mut child_down = [[0.0; 3]; MAX_KK];
        let mut masked = [[0.0; 3]; MAX_KK];
        let tri = self.geo.quads[el.piece.surface].tri;
        let basis = self.tri_basis;
        for i in 0..4u32 {
            let (dt, ds) = ((i / 2) as usize, (i % 2) as usize);
            // a triangle's children by its own two-scale relation
            if tri {
                basis.push(&total[..kk], i as usize, &mut child_down[..kk]);
            } else {
                push(self.filters, &total[..kk], dt, ds, &mut child_down[..kk]);
            }
            self.push_pull(first + i, &child_down[..kk], change, norm);
            let child = &self.elements[(first + i) as usize];
            // a partly covered parent projects its children's B on its exposed part: the
            // parent's G⁺ of the sum of the children's masked moments G_c b_c
            let moments = match (&self.elements[e as usize].exposure, &child.exposure) {
                (Exposure::Partial(_), Exposure::Partial(p)) => {
                    Partial::apply(&p.gram, &child.b, &mut masked[..kk]);
                    &masked[..kk]
                }
                (Exposure::Partial(_), Exposure::Covered) => {
                    masked[..kk].fill([0.0; 3]);
                    &masked[..kk]
                }
                _ => &child.b[..],
            };
            if tri {
                basis.pull(moments, i as usize, &mut b[..kk]);
            } else {
                pull(self.filters, moments, dt, ds, &mut b[..kk]);
            }
        }
        if let Exposure::Partial(p) = &self.elements[e as usize].exposure {
            Partial::apply(&p.inverse, &b[..kk], &mut masked[..kk]);
            b[..kk].copy_from_slice(&masked[..kk]);
        }
        self.elements[e as usize].b.copy_from_slice(&b[..kk]);
    }

    /// Fields of B, E and H over each surface, from the leaves.
    fn fields(&self, pick: impl Fn(&Element) -> Vec<Rgb>) -> Vec<Field> {
        (0..self.quads.len())
            .map(|s| self.field(s, &pick))
            .collect()
    }

    /// The field of surface `s` from its leaves.
    fn field(&self, s: usize, pick: &impl Fn(&Element) -> Vec<Rgb>) -> Field {
        let (order, res) = (self.k - 1, 1usize << self.deepest[s]);
        let mut leaves = Vec::new();
        self.collect_leaves(s as u32, pick, &mut leaves);
        if self.geo.quads[s].tri {
            Field::triangle(order, res, leaves)
        } else {
            Field::from_leaves(2, order, res, leaves)
        }
    }

    /// The fields of the numbers (surface and cell means): each element's B, and on a
    /// parallelogram with a covered part, each partly covered leaf split down to the mask's
    /// sub-cells ([`SUB`] per finest cell, at most [`MAX_LEVEL`] levels in all) into
    /// pieces that are wholly exposed (the exposed part's polynomial, pushed down exactly) or
    /// wholly covered (E). The element's own projection onto its polynomials keeps its mean but
    /// spreads the covered part's E and the exposed part's light over the cells inside it (a
    /// cube standing on a top not much larger than itself: the covered cells 0.022 for 0). A
    /// triangle is one cell, whose mean the projection keeps.
    fn reported_fields(&self) -> Vec<Field> {
        let reported = |e: &Element| e.reported(&e.b, &e.e);
        (0..self.quads.len())
            .map(|s| {
                let Some(mask) = self.masks[s].as_ref().filter(|_| !self.geo.quads[s].tri) else {
                    return self.field(s, &reported);
                };
                let level = self.deepest[s];
                let finest = (level + SUB.trailing_zeros()).min(level.max(MAX_LEVEL));
                let mut leaves = Vec::new();
                self.collect_reported(s as u32, mask, finest, &mut leaves);
                Field::from_leaves(2, self.k - 1, 1 << finest, leaves)
            })
            .collect()
    }

    fn collect_reported(&self, e: u32, mask: &Mask, finest: u32, out: &mut Vec<Leaf>) {
        let el = &self.elements[e as usize];
        if !el.is_leaf() {
            for i in 0..4 {
                self.collect_reported(el.children + i, mask, finest, out);
            }
            return;
        }
        let whole = MaskedPiece {
            s: el.piece.s,
            t: el.piece.t,
            area: el.area,
            exposed: el.b.clone(),
            covered: el.e.clone(),
            projected: el.reported(&el.b, &el.e),
        };
        if let Exposure::Partial(_) = el.exposure {
            self.split_masked(mask, whole, finest - el.level, out);
        } else {
            out.push(whole.leaf(&whole.projected));
        }
    }

    /// Splits a partly covered piece until each part is wholly exposed or wholly covered, or
    /// `depth` runs out (then the parent's projection, pushed down, as before the split).
    fn split_masked(&self, mask: &Mask, p: MaskedPiece, depth: u32, out: &mut Vec<Leaf>) {
        match mask.coverage(p.s, p.t) {
            Some(false) => return out.push(p.leaf(&p.exposed)),
            Some(true) => return out.push(p.leaf(&p.covered)),
            None if depth == 0 => return out.push(p.leaf(&p.projected)),
            None => {}
        }
        let kk = self.k * self.k;
        for i in 0..4 {
            let (dt, ds) = (i / 2, i % 2);
            let half = |r: [f64; 2], d: usize| {
                let m = 0.5 * (r[0] + r[1]);
                if d == 0 {
                    [r[0], m]
                } else {
                    [m, r[1]]
                }
            };
            let down = |parent: &[Rgb]| {
                let mut child = vec![[0.0; 3]; kk];
                push(self.filters, parent, dt, ds, &mut child);
                child
            };
            let child = MaskedPiece {
                s: half(p.s, ds),
                t: half(p.t, dt),
                area: 0.25 * p.area,
                exposed: down(&p.exposed),
                covered: down(&p.covered),
                projected: down(&p.projected),
            };
            self.split_masked(mask, child, depth - 1, out);
        }
    }

    fn collect_leaves(&self, e: u32, pick: &impl Fn(&Element) -> Vec<Rgb>, out: &mut Vec<Leaf>) {
        let el = &self.elements[e as usize];
        if el.is_leaf() {
            let f = 1.0 / el.area.sqrt();
            out.push(Leaf {
                s: el.piece.s,
                t: el.piece.t,
                coeffs: pick(el).iter().map(|v| v.map(|x| x * f)).collect(),
                upper: el.piece.upper,
            });
            return;
        }
        for i in 0..4 {
            self.collect_leaves(el.children + i, pick, out);
        }
    }

    /// The links as a picture of the operator: the finest cells of every surface in Z-order
    /// (so that every element covers one run of them), receivers down, sources across; each
    /// link fills its block with the mean kernel value it carries, |T_00| / √(A_r A_s).
    fn picture(&self, max_side: usize) -> crate::methods::compress::MagnitudePicture {
        // each surface's finest cells, one run after another
        let mut start = vec![0usize; self.quads.len() + 1];
        for (i, &l) in self.deepest.iter().enumerate() {
            start[i + 1] = start[i] + (1usize << (2 * l));
        }
        let run = |e: &Element| {
            let shift = self.deepest[e.piece.surface] - e.level;
            let (cs, ct) = ((e.cell[0] as usize) << shift, (e.cell[1] as usize) << shift);
            let lo = start[e.piece.surface] + morton(cs, ct);
            lo..lo + (1usize << (2 * shift))
        };
        let blocks = self.links.iter().map(|(l, block)| {
            let (r, s) = (
                &self.elements[l.recv as usize],
                &self.elements[l.src as usize],
            );
            let v = f64::from(block[0].abs()) / (r.area * s.area).sqrt();
            (run(r), run(s), v)
        });
        crate::methods::compress::block_picture(start[self.quads.len()], max_side, blocks)
    }

    fn stats(&self) -> HierarchyStats {
        HierarchyStats {
            elements: self.elements.len(),
            leaves: self.elements.iter().filter(|e| e.is_leaf()).count(),
            links: self.links.len() + self.cluster_links.len(),
            levels: self
                .elements
                .iter()
                .map(|e| e.level as usize + 1)
                .max()
                .unwrap_or(0),
            refinements: self.refinements,
            rays: self.rays,
            min_element_size: Some(self.sizing.min_element_size),
        }
    }
}

/// Adds a link's transfer to the receiver's H: h += T b, T the link's k² × k² block (rows by
/// receiver coefficient) and b the source's coefficients.
fn gather(h: &mut [Rgb], block: &[f32], b: &[Rgb]) {
    for (hr, row) in h.iter_mut().zip(block.chunks_exact(b.len())) {
        for (&v, bc) in row.iter().zip(b) {
            let v = f64::from(v);
            for ch in 0..3 {
                hr[ch] += v * bc[ch];
            }
        }
    }
}

/// The patches of each surface as the document names them, in the order of their first.
fn surface_groups(quads: &[Quad]) -> Vec<Vec<u32>> {
    let mut groups: Vec<Vec<u32>> = Vec::new();
    let mut index = std::collections::HashMap::new();
    for (i, q) in quads.iter().enumerate() {
        let g = *index.entry(q.name.as_str()).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(i as u32);
    }
    groups
}

/// The memory the links' blocks may take.
const LINK_BYTES: usize = 1 << 30;

/// The memory the pairs waiting to be judged at one level of the refinement may take.
const FRONTIER_BYTES: usize = 1 << 31;

/// The most pairs of a level judged at once ([`Budget::chunk`]).
const CHUNK: usize = 1 << 16;

/// The most the refinement may hold, from the memory it allows itself.
#[derive(Debug, Clone, Copy)]
struct Budget {
    /// The links made: a block of k⁴ numbers (single precision, [`Links`]) and the link's
    /// ends and factors each, within [`LINK_BYTES`].
    links: usize,
    /// The pairs of one level's frontier, [`refine::PAIR_BYTES`] each, within
    /// [`FRONTIER_BYTES`].
    pairs: usize,
    /// The pairs judged at once. A pair's verdict and slot take about a hundred bytes: a
    /// frontier of millions (a cluster tree of 10⁶ triangles linked to itself) is judged in
    /// chunks of this many, in order, so that those stay within a few MB. A frontier no larger
    /// is judged in one.
    chunk: usize,
}

impl Budget {
    fn of_order(order: usize) -> Self {
        Budget {
            links: LINK_BYTES
                / (std::mem::size_of::<f32>() * (order + 1).pow(4) + std::mem::size_of::<Link>()),
            pairs: FRONTIER_BYTES / refine::PAIR_BYTES,
            chunk: CHUNK,
        }
    }
}

/// Which bound of the [`Budget`] the refinement reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Overrun {
    Links,
    Pairs,
}

/// How far above E_max / (1 − ρ_max) a surface's mean B may come before the iteration is taken
/// to diverge. That bound holds for the exact solution (every form factor sum is at most 1);
/// a Galerkin approximation overshoots it by far less, and a diverging iteration grows past
/// it geometrically.
const BOUND_FACTOR: f64 = 1e3;

impl Hierarchy<'_> {
    /// Why the iteration has diverged, if it has: B is no longer finite, or a surface's mean
    /// exceeds [`BOUND_FACTOR`] times the physical bound E_max / (1 − ρ_max). A solver that
    /// went on would return numbers of 10³⁷ as if they were a solution.
    fn unbounded(&self, residual: f64) -> Option<String> {
        if !residual.is_finite() {
            return Some("B is no longer finite".into());
        }
        let emission = self
            .quads
            .iter()
            .flat_map(|q| q.material.emission)
            .fold(0.0, f64::max);
        let rho = self.rho.iter().copied().fold(0.0, f64::max).min(1.0 - 1e-9);
        let bound = emission / (1.0 - rho);
        let (i, worst) = (0..self.quads.len())
            .map(|i| {
                let root = &self.elements[i];
                let top = root.b[0].iter().map(|b| b.abs()).fold(0.0, f64::max);
                (i, top / root.area.sqrt())
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        (!worst.is_finite() || worst > BOUND_FACTOR * bound).then(|| {
            format!(
                "surface {i}'s mean B reached {worst:.3e}, more than {BOUND_FACTOR} times \
                 E_max / (1 − ρ_max) = {bound:.3e}"
            )
        })
    }
}

/// Whether the edge of `quad`'s emission region passes through the inside of `piece`.
fn straddles_emission(quad: &Quad, piece: Piece) -> bool {
    let (rs, rt) = quad.emission_region;
    let inside =
        rs[0] <= piece.s[0] && piece.s[1] <= rs[1] && rt[0] <= piece.t[0] && piece.t[1] <= rt[1];
    refine::peak_emission(quad, piece) > 0.0 && !inside
}

/// Why the refinement stopped: the caller's cancel, or a bound of its budget.
fn stopped(h: &Hierarchy, _: Cancelled) -> JobError {
    match h.too_large {
        Some(Overrun::Links) => JobError::TooLarge {
            links: h.budget.links,
            order: h.k - 1,
        },
        Some(Overrun::Pairs) => JobError::TooManyPairs {
            pairs: h.budget.pairs,
        },
        None => JobError::Cancelled,
    }
}

/// Solves a job by hierarchical wavelet radiosity at the given order, with elements no smaller
/// than the document's `min_element_size` and, when given, no finer than `resolution`.
pub(crate) fn solve(
    job: &Job,
    order: usize,
    resolution: Option<usize>,
    rules: &Rules,
    progress: &dyn Progress,
) -> Result<Solution, JobError> {
    let SceneKind::ThreeD(quads) = &job.scene.kind else {
        return Err(JobError::Unsupported {
            method: "hierarchical",
            scene: job.scene.kind.name(),
        });
    };
    let mut timings = BTreeMap::new();
    let t = Instant::now();
    progress.report(Phase::Refinement, 0.0);
    let geo = Geometry::new(quads);
    let sizing = Sizing::new(&geo.quads, job.solver.min_element_size, resolution);
    let mut h = Hierarchy::new(&geo, quads, order, sizing, job.solver.epsilon, rules);
    h.gauss_seidel = job.solver.iteration == crate::scene::Iteration::GaussSeidel;
    h.link_all(progress).map_err(|c| stopped(&h, c))?;
    let mut refine_ms = ms(t);
    let mut solve_ms = 0.0;
    let mut history = Vec::new();
    let mut iterations = 0;
    let mut converged = false;
    let mut residual = f64::INFINITY;
    // the solves before the last only steer the refinement, for which B to ROUGH will do;
    // the last one (no link changed, or the passes ran out) goes to the document's tolerance
    let mut last = false;
    let mut x = Vec::new();
    for pass in 0..=MAX_PASSES {
        // each pass sweeps a new operator: its dominant mode is measured afresh
        let mut lyusternik = Lyusternik::default();
        last |= pass == MAX_PASSES;
        let tolerance = if last {
            job.solver.tolerance
        } else {
            job.solver.tolerance.max(ROUGH)
        };
        let t = Instant::now();
        converged = false;
        while iterations < job.solver.max_iterations {
            progress.check()?;
            residual = h.sweep();
            iterations += 1;
            history.push(residual);
            if let Some(reason) = h.unbounded(residual) {
                return Err(JobError::Diverged {
                    iteration: iterations,
                    reason,
                });
            }
            progress.report(
                Phase::Solve,
                (iterations as f64 / job.solver.max_iterations as f64).min(1.0),
            );
            if residual < tolerance {
                converged = residual < job.solver.tolerance;
                break;
            }
            // the last sweep is always a sweep, so that B and H agree
            if iterations + 1 < job.solver.max_iterations {
                h.coefficients(&mut x);
                if lyusternik.step(&mut x).is_some() {
                    h.set_coefficients(&x);
                }
            }
        }
        solve_ms += ms(t);
        if last {
            break;
        }
        let t = Instant::now();
        progress.check()?;
        progress.report(Phase::Refinement, (pass + 1) as f64 / MAX_PASSES as f64);
        let refined = h.rerefine(progress).map_err(|c| stopped(&h, c))?;
        refine_ms += ms(t);
        last = refined == 0;
    }

    // the sweeps' light is not needed for the results: held through them, it was 113 MB
    // more of the 81 icospheres' peak (1 032 against 920 MB)
    h.lights = clustered::Lights::default();
    timings.insert("refinement".into(), refine_ms);
    timings.insert("solve".into(), solve_ms);
    // the numbers count a covered part as B = E, H = 0; the images show the exposed part's
    // polynomial, up to the outline
    let fields = h.reported_fields();
    let shown = h.masks.iter().any(Option::is_some).then(|| {
        h.fields(|e| match e.exposure {
            Exposure::Covered => e.e.clone(),
            _ => e.b.clone(),
        })
    });
    let emission = h.fields(|e| e.e.clone());
    let zero = vec![[0.0; 3]; h.k * h.k];
    let irradiance = h.fields(|e| e.reported(&e.h, &zero));
    // the links' coefficients that are not zero: what the hierarchy keeps of the operator
    let (kept_entries, magnitudes) = crate::methods::compress::ranked(
        || {
            h.links
                .coefficients()
                .iter()
                .map(|&v| f64::from(v.abs()))
                .filter(|v| *v > 0.0)
        },
        job.output.coefficients,
    );
    // Σ‖block‖² per pair of surfaces, for eq. (5) by Parseval over the link blocks (none
    // where eq. (5) is sampled instead; only meshes, all of triangles, have clusters, and
    // eq. (5) is sampled with triangles, so every link here is between elements)
    let surfaces = h.quads.len();
    let sample = kernel_error::sampled_on(h.geo.quads.iter().any(|q| q.tri), quads.len());
    let mut kept_squares = vec![0.0; if sample { 0 } else { surfaces * surfaces }];
    for (l, block) in h.links.iter().filter(|_| !sample) {
        let (r, s) = (&h.elements[l.recv as usize], &h.elements[l.src as usize]);
        kept_squares[r.piece.surface * surfaces + s.piece.surface] +=
            block.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>();
    }
    // eq. (5) over the pairs of surfaces needs their blocks' squares, which cluster links do
    // not have, and costs s² quadratures: with triangles or many surfaces it is sampled
    let sampled = sample.then(|| {
        let t = Instant::now();
        let s = h.sampled_kernel_error(&surface_groups(quads), kernel_error::PAIRS);
        timings.insert("kernel_error".into(), ms(t));
        s
    });
    let leaf_b: Vec<Rgb> = h
        .elements
        .iter()
        .filter(|e| e.is_leaf())
        .flat_map(|e| e.b.iter().copied())
        .collect();
    Ok(Solution {
        fields,
        shown,
        emission,
        irradiance,
        // the space is the leaves' polynomials; the projection method would hold all of its
        // basis_size² couplings, the links hold the nonzero ones they keep
        basis_size: leaf_b.len(),
        matrix_entries: leaf_b.len() * leaf_b.len(),
        kept_entries,
        cut: 0.0,
        magnitudes,
        picture: Some(h.picture(512)),
        solved: Solved {
            b: leaf_b,
            iterations,
            history,
            residual,
            converged,
        },
        kernel_error: sampled.as_ref().map(|s| s.value),
        left_out: sampled
            .as_ref()
            .map(|s| s.left_out.clone())
            .unwrap_or_default(),
        kernel_error_sampling: sampled.map(|s| crate::result::KernelErrorSampling {
            point_pairs: kernel_error::PAIRS,
            standard_error: s.standard_error,
        }),
        hierarchy: Some(h.stats()),
        timings,
        kept_squares,
        kernel_evaluations: Some(h.evaluations.into_inner()),
    })
}

fn ms(t: Instant) -> f64 {
    (t.elapsed().as_secs_f64() * 1e6).round() / 1e3
}

/// A piece of a partly covered leaf with the three polynomials it may report (coefficients
/// orthonormal in its area): the exposed part's, E, and the leaf's projection of both.
struct MaskedPiece {
    s: [f64; 2],
    t: [f64; 2],
    area: f64,
    exposed: Vec<Rgb>,
    covered: Vec<Rgb>,
    projected: Vec<Rgb>,
}

impl MaskedPiece {
    fn leaf(&self, coeffs: &[Rgb]) -> Leaf {
        let f = 1.0 / self.area.sqrt();
        Leaf {
            s: self.s,
            t: self.t,
            coeffs: coeffs.iter().map(|v| v.map(|x| x * f)).collect(),
            upper: false,
        }
    }
}

/// Interleaves the bits of (s, t): the Z-order index of a cell of a quadtree level.
fn morton(s: usize, t: usize) -> usize {
    let mut out = 0;
    for b in 0..(usize::BITS / 2) as usize {
        out |= ((s >> b) & 1) << (2 * b) | ((t >> b) & 1) << (2 * b + 1);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hierarchy of the tests here, before any link: order 1, elements down to 0.25 m,
    /// ε = 1e-3.
    fn hierarchy<'g>(geo: &'g Geometry, quads: &'g [Quad]) -> Hierarchy<'g> {
        let sizing = Sizing::new(&geo.quads, Some(0.25), None);
        Hierarchy::new(geo, quads, 1, sizing, 1e-3, &Rules::default())
    }

    /// The hierarchy of `quads` at order 1 and ε = 1e-3, the document's default element
    /// size and rules, before any link.
    pub(super) fn at_defaults<'g>(geo: &'g Geometry, quads: &'g [Quad]) -> Hierarchy<'g> {
        let sizing = Sizing::new(&geo.quads, None, None);
        Hierarchy::new(geo, quads, 1, sizing, 1e-3, &Rules::default())
    }

    /// A 4 × 4 m ceiling at height 2 facing down: a mesh of 4 × 4 squares, each split along
    /// its diagonal.
    fn ceiling() -> serde_json::Value {
        let n = 4;
        let positions: Vec<[f64; 3]> = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| [i as f64, 2.0, j as f64]))
            .collect();
        let triangles: Vec<[usize; 3]> = (0..n)
            .flat_map(|j| {
                (0..n).flat_map(move |i| {
                    let a = j * (n + 1) + i;
                    [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
                })
            })
            .collect();
        serde_json::json!({"positions": positions, "triangles": triangles})
    }

    /// A corner of a 4 × 4 m room (a floor and one wall of parallelograms) under the meshed
    /// [`ceiling`], lit by a light hung just below it: links of every kind, element and
    /// cluster, affine and not.
    pub(super) fn corner_under_a_meshed_ceiling() -> Vec<Quad> {
        patches(&serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "ceiling", "mesh": ceiling(), "reflectance": 0.7},
            {"name": "floor", "corners": [[0, 0, 0], [0, 0, 4], [4, 0, 4], [4, 0, 0]],
             "reflectance": [0.7, 0.5, 0.3]},
            {"name": "wall", "corners": [[0, 0, 0], [0, 2, 0], [0, 2, 4], [0, 0, 4]],
             "reflectance": 0.6},
            {"name": "light", "corners": [[1, 1.9, 1], [3, 1.9, 1], [3, 1.9, 3], [1, 1.9, 3]],
             "reflectance": 0.0, "emission": 1.0}]},
            "solver": {"method": "hierarchical"}}))
    }

    /// The patches of a 3D job document.
    pub(super) fn patches(doc: &serde_json::Value) -> Vec<Quad> {
        let job = crate::scene::parse_value(doc, &crate::scene::Limits::default()).unwrap();
        match job.scene.kind {
            SceneKind::ThreeD(scene) => scene.patches,
            _ => unreachable!(),
        }
    }

    /// The root element of a triangle patch that a solid covers in part measures its covered
    /// part with the triangle basis, as its children do: a ceiling of 32 triangles with a
    /// light hung 1 cm below four of its squares has its eight triangles under the light
    /// covered (two of them hold none of the light's corners) and the probed ones beside it
    /// open (up to the probe's strip along the light's edge).
    /// Measured with the tensor Gram matrices of the triangle's (s, t) square, half of which
    /// lies outside it, the open ones came out half covered, with wild polynomials on them.
    #[test]
    fn a_triangle_roots_covered_part_is_measured_on_the_triangle() {
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "ceiling", "mesh": ceiling(), "reflectance": 0.5},
            {"name": "light", "corners": [[1, 1.99, 1], [3, 1.99, 1], [3, 1.99, 3], [1, 1.99, 3]],
             "reflectance": 0.0, "emission": 1.0}]},
            "solver": {"method": "hierarchical"}});
        let quads = &patches(&doc);
        let geo = Geometry::new(quads);
        let h = hierarchy(&geo, quads);
        // the share of each probed triangle that is exposed: 0 under the light, 1 elsewhere,
        // but for the probe's strip along the light's edge (a sixteenth of a cell)
        let exposed: Vec<f64> = (0..geo.quads.len())
            .filter(|&i| geo.quads[i].tri && h.masks[i].is_some())
            .map(|i| match &h.elements[i].exposure {
                Exposure::Covered => 0.0,
                Exposure::Open => 1.0,
                Exposure::Partial(p) => p.fraction(),
            })
            .collect();
        let under = exposed.iter().filter(|&&f| f < 0.1).count();
        let open = exposed.iter().filter(|&&f| f > 0.9).count();
        assert_eq!(under, 8, "the eight triangles under the light: {exposed:?}");
        assert!(open > 0, "{exposed:?}");
        assert_eq!(under + open, exposed.len(), "{exposed:?}");
    }

    /// A solve stops with `Diverged` when a surface's mean B leaves the physical bound
    /// E_max / (1 − ρ_max) far behind or is no longer finite, not before: the closed cube
    /// (E = 1 on its ceiling, ρ = ½: the bound is 2) at B = 1.9 everywhere is fine, at
    /// 10³ × 2 on one wall it is not.
    #[test]
    fn a_solve_whose_b_leaves_the_physical_bound_has_diverged() {
        let quads = super::refine::tests::cube();
        let geo = Geometry::new(&quads);
        let mut h = at_defaults(&geo, &quads);
        let set = |h: &mut Hierarchy, i: usize, b: f64| {
            let a = h.elements[i].area;
            h.elements[i].b[0] = [b * a.sqrt(); 3];
        };
        (0..6).for_each(|i| set(&mut h, i, 1.9));
        assert_eq!(h.unbounded(0.1), None);
        assert!(h.unbounded(f64::NAN).is_some());
        set(&mut h, 3, 2.01 * BOUND_FACTOR);
        let reason = h.unbounded(0.1).expect("diverged");
        assert!(reason.contains("surface 3"), "{reason}");
    }

    /// The partly visible links made before B is known carry the share of the rays through
    /// the first solve; then each takes the share of the light from its own grid of fresh
    /// rays (as many as judged it). In the corner under the meshed ceiling, the light
    /// hung below the ceiling hides part of it from the floor and the wall, and the ceiling is
    /// brightest above the light: the share of the light differs from the share of the rays.
    #[test]
    fn links_made_before_b_is_known_take_the_share_of_the_light_after_the_first_solve() {
        let quads = &corner_under_a_meshed_ceiling();
        let geo = Geometry::new(quads);
        let mut h = hierarchy(&geo, quads);
        h.link_all(&crate::progress::Silent).unwrap();
        let unlit: Vec<(u32, u32, u8)> = h
            .links
            .ends()
            .iter()
            .filter_map(|l| l.factors.unlit.map(|n| (l.recv, l.src, n)))
            .collect();
        assert!(unlit.len() > 10, "{} partly visible links", unlit.len());
        while h.sweep() > 1e-6 {}
        h.typical = h.typical_radiosity();
        h.solved = true;
        let (links, hidden) = (h.links.len(), h.hidden.len());
        let mut kept = std::mem::take(&mut h.links);
        let lit = h.relight(&mut kept);
        h.links = kept;
        assert!(h.links.ends().iter().all(|l| l.factors.unlit.is_none()));
        assert_eq!(links - h.links.len(), unlit.len());
        assert_eq!(lit.len() + h.hidden.len() - hidden, unlit.len());
        let mut differ = 0;
        for (r, s, x, v) in lit {
            assert!(x.unlit.is_none());
            let &(_, _, n) = unlit.iter().find(|u| (u.0, u.1) == (r, s)).unwrap();
            let n = usize::from(n);
            assert_eq!(v, h.share_of_light(r, s, n, None, &mut 0), "{r} ← {s}");
            let (pr, ps) = (h.elements[r as usize].piece, h.elements[s as usize].piece);
            let seed = crate::three_d::visibility::pair_seed(h.identity(r), h.identity(s)) ^ 2;
            let mask = h.masks[pr.surface].as_ref();
            let all = crate::three_d::visibility::Occluders::all(&geo.bvh);
            let rays = crate::three_d::visibility::visible_fraction_over(
                &all, pr, mask, ps, n, seed, &mut 0,
            );
            differ += usize::from((rays.whole - v.whole).abs() > 1e-3);
        }
        assert!(differ > 0, "the light changed no fraction");
    }

    /// Gauss–Seidel sweeps reach the fixed point of the Jacobi sweeps, on the same links, in
    /// fewer sweeps: a room of parallelograms with a meshed ceiling (so that links with a
    /// cluster at an end take part) lit by a hung light. Both iterate to a relative change of
    /// 1e-12; every element's B agrees to 1e-9 of the largest.
    #[test]
    fn gauss_seidel_reaches_the_jacobi_fixed_point_in_fewer_sweeps() {
        let quads = &corner_under_a_meshed_ceiling();
        let geo = Geometry::new(quads);
        let solve = |gauss_seidel: bool| {
            let mut h = hierarchy(&geo, quads);
            h.link_all(&crate::progress::Silent).unwrap();
            h.gauss_seidel = gauss_seidel;
            let mut sweeps = 0;
            while h.sweep() > 1e-12 {
                sweeps += 1;
                assert!(sweeps < 500);
            }
            let b: Vec<Rgb> = h.elements.iter().flat_map(|e| e.b.clone()).collect();
            (b, sweeps, h.links.len(), h.cluster_links.len())
        };
        let (jacobi, gauss_seidel) = (solve(false), solve(true));
        assert_eq!((jacobi.2, jacobi.3), (gauss_seidel.2, gauss_seidel.3));
        assert!(jacobi.3 > 0, "no link with a cluster at an end");
        let largest = jacobi
            .0
            .iter()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for (a, b) in jacobi.0.iter().zip(&gauss_seidel.0) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-9 * largest, "{a:?} {b:?}");
            }
        }
        assert!(
            gauss_seidel.1 < jacobi.1,
            "{} Gauss–Seidel sweeps, {} Jacobi",
            gauss_seidel.1,
            jacobi.1
        );
        eprintln!(
            "{} Gauss–Seidel sweeps, {} Jacobi",
            gauss_seidel.1, jacobi.1
        );
    }

    /// The budget bounds the links a refinement makes and, apart, the pairs one level holds:
    /// a link budget of exactly the links made lets the refinement finish (the pairs of its
    /// fine levels, most of which end split, hidden or inert, are not links); one link
    /// fewer stops it with the link budget; a bound on the pairs below the first level's
    /// stops it with that bound. Both say what they reached.
    #[test]
    fn the_refinement_stops_at_the_links_it_makes_and_apart_at_the_pairs_it_holds() {
        let quads = &corner_under_a_meshed_ceiling();
        let geo = Geometry::new(quads);
        let refine = |budget: Budget| {
            let mut h = hierarchy(&geo, quads);
            h.budget = budget;
            let made = h.link_all(&crate::progress::Silent);
            (made.map_err(|c| stopped(&h, c)), h.links.len())
        };
        let unbounded = Budget {
            links: usize::MAX,
            pairs: usize::MAX,
            chunk: usize::MAX,
        };
        let (made, links) = refine(unbounded);
        assert!(made.is_ok() && links > 100, "{links} links");
        let (made, exact) = refine(Budget { links, ..unbounded });
        assert!(made.is_ok(), "{made:?}");
        assert_eq!(exact, links);
        let (made, _) = refine(Budget {
            links: links - 1,
            ..unbounded
        });
        assert_eq!(
            made,
            Err(JobError::TooLarge {
                links: links - 1,
                order: 1
            })
        );
        let (made, _) = refine(Budget {
            pairs: 1,
            ..unbounded
        });
        assert_eq!(made, Err(JobError::TooManyPairs { pairs: 1 }));
    }

    /// A re-refinement counts the links it keeps against the link budget with those it makes:
    /// a budget of the links before the second re-refinement, which makes fewer than it keeps
    /// and refines some, stops it with the link budget; one of the links after lets it finish.
    #[test]
    fn a_re_refinement_counts_the_links_it_keeps() {
        let quads = &corner_under_a_meshed_ceiling();
        let geo = Geometry::new(quads);
        let solve = |h: &mut Hierarchy| while h.sweep() > 1e-9 {};
        let twice_solved = || {
            let mut h = hierarchy(&geo, quads);
            h.link_all(&crate::progress::Silent).unwrap();
            solve(&mut h);
            h.rerefine(&crate::progress::Silent).unwrap();
            solve(&mut h);
            h
        };
        let mut h = twice_solved();
        let before = h.links.len();
        assert!(h.rerefine(&crate::progress::Silent).unwrap() > 0);
        let after = h.links.len();
        assert!(after > before, "{before} → {after} links");
        let mut h = twice_solved();
        h.budget.links = before;
        let made = h.rerefine(&crate::progress::Silent);
        assert_eq!(
            made.map_err(|c| stopped(&h, c)),
            Err(JobError::TooLarge {
                links: before,
                order: 1
            })
        );
        let mut h = twice_solved();
        h.budget.links = after;
        assert!(h.rerefine(&crate::progress::Silent).is_ok());
    }

    /// A level judged in chunks makes the refinement that it makes judged at once: the same
    /// elements, links and cluster links, and, solved, the same B (to rounding: the elements
    /// are numbered in another order, so sums run in another order).
    #[test]
    fn a_level_judged_in_chunks_refines_as_judged_at_once() {
        let quads = &corner_under_a_meshed_ceiling();
        let geo = Geometry::new(quads);
        let solve = |chunk: usize| {
            let mut h = hierarchy(&geo, quads);
            h.budget.chunk = chunk;
            h.link_all(&crate::progress::Silent).unwrap();
            while h.sweep() > 1e-12 {}
            let counts = (
                h.elements.len(),
                h.links.len(),
                h.cluster_links.len(),
                h.rays,
            );
            let means: Vec<Rgb> = (0..quads.len()).map(|i| h.elements[i].b[0]).collect();
            (counts, means)
        };
        let (once, chunked) = (solve(usize::MAX), solve(5));
        assert_eq!(once.0, chunked.0);
        assert!(once.0 .2 > 0, "no link with a cluster at an end");
        for (a, b) in once.1.iter().zip(&chunked.1) {
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() <= 1e-12 * a[c].abs().max(1e-12),
                    "{a:?} {b:?}"
                );
            }
        }
    }
}

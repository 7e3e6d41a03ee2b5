//! The tolerance of the refinement oracle for each receiver: how the document's ε, which is
//! relative to the brightest emission (`docs/job-document.md`), becomes the bound that each
//! link's estimate ([`super::refine`], [`super::clustered`]) is held to.
//!
//! Two rules share it out, both measured on the scene and neither on a kind of scene:
//!
//! 1. **Sources add up** (the weight w_RS). A receiver R gathers inter-reflected light from
//!    every surface it faces, and the errors of coarse links share a sign (a coarse link
//!    averages a source's bright spot over a kernel that peaks at it), so R's tolerance is
//!    shared among its sources: a link from a non-emitting surface S is held to ε / w_RS, where
//!    1 / w_RS = max(F_RS / Σ_S' F_RS', 1 / N_R) is S's share, F_RS the unoccluded form factor
//!    from R to S and N_R the number of non-emitting surfaces facing R. A source gets its share
//!    of R's light, and at least an equal share of the count: the shares add up to at most 2
//!    (Σ F_RS / Σ F = 1, Σ 1 / N_R = 1), so the errors of all the links into R stay within
//!    twice ε whatever their signs. (The BF criterion of Hanrahan, Salzman and Aupperle 1991
//!    weighs one link by what it carries; this shares a receiver's tolerance among the links
//!    that add up in it.) The largest source gets Σ F / max F, the number of sources as large
//!    as it: a surface of a few large neighbours is held to a few times ε for them, and a
//!    small source to the count, as every source was once (the count took 7.3 M links for 81
//!    spheres in a room). The largest source's weight alone, for every source, lets the shares
//!    add up to N_R / w_R: the corner boxes of the room with 7 × 7 boxes came out 5.5 % bright
//!    on their faces toward the walls at ε = 1e-3, and converged slowly (9.4, 7.4, 5.5 % from
//!    ε = 4e-3); with the shares, 0.31 %. F_RS is sampled: 64 area-stratified points of R,
//!    each to every patch of S in closed form ([`crate::three_d::transfer::point_polygon`]), or
//!    to 64 area-stratified triangles of a larger mesh, each standing for its share of the
//!    mesh's area; of each patch only its front, which alone sends light (the closed form
//!    counts either side: a closed mesh's far half and a surface seen from behind its plane
//!    counted as much as what faces the point). A link from a cluster, which may hold many
//!    surfaces, takes the weight of R's largest source.
//! 2. **Relative accuracy** (the share of a dim receiver). The estimate is absolute, so a
//!    receiver at a tenth of the typical B would take links ten times too coarse for the
//!    relative accuracy of the others. A receiver element whose mean B is below the typical B
//!    (the area-weighted mean over the non-emitting surfaces, from the solve before) in any
//!    channel its surface reflects gets the ratio as its share of the tolerance, the least over
//!    those channels, down to [`Rules::dim_share`]. The element's own B, not its surface's:
//!    the floor in front of the Cornell box's short block, in the block's shadow at a tenth of
//!    the floor's mean, came out 28 % bright at its foot with the floor's share. Before the
//!    first solve B is only E, and the whole tolerance holds.

use super::Hierarchy;
use crate::scene::Quad;
use crate::three_d::cluster::Bound;
use crate::three_d::geometry::{dot, sub, Piece, V3};
use crate::three_d::projection::Geometry;
#[cfg(doc)]
use crate::three_d::rules::Rules;
use crate::three_d::transfer::point_polygon;
use rayon::prelude::*;

/// Points of a receiver surface, and pieces of a large mesh as a source, in the sampled
/// form factors of w_R.
const SAMPLES: usize = 64;

/// The weights w_RS = 1 / max(F(R → S) / Σ_S' F(R → S'), 1 / N_R) of every pair of document
/// surfaces (a mesh counts once), over the N_R surfaces S' that emit nothing and face R.
pub(super) fn indirect_weights(geo: &Geometry, quads: &[Quad], groups: &[Vec<u32>]) -> Weights {
    let mut of = vec![0; quads.len()];
    for (g, members) in groups.iter().enumerate() {
        members.iter().for_each(|&p| of[p as usize] = g);
    }
    let bounds: Vec<Bound> = groups
        .iter()
        .map(|g| Bound::of_patches(&geo.quads, g))
        .collect();
    let dark: Vec<bool> = groups
        .iter()
        .map(|g| {
            g.iter().all(|&p| {
                quads[p as usize]
                    .material
                    .emission
                    .iter()
                    .all(|&e| e == 0.0)
            })
        })
        .collect();
    let faces = |a: usize, b: usize| match (&groups[a][..], &groups[b][..]) {
        ([i], [j]) => geo.facing(*i as usize, *j as usize),
        _ => bounds[a].facing(&bounds[b]),
    };
    let points: Vec<Vec<(V3, V3)>> = groups.iter().map(|g| receiver_points(geo, g)).collect();
    let sources: Vec<Vec<SourcePiece>> = groups.iter().map(|g| source_pieces(geo, g)).collect();
    let rows: Vec<Row> = (0..groups.len())
        .into_par_iter()
        .map(|a| {
            let f: Vec<(u32, f64)> = (0..groups.len())
                .filter(|&b| b != a && dark[b] && faces(a, b))
                .map(|b| (b as u32, form_factor(&points[a], &sources[b])))
                .collect();
            Row::of(&f)
        })
        .collect();
    Weights {
        of: of.iter().map(|&g| g as u32).collect(),
        rows,
    }
}

/// The weights w_RS of one receiver surface R.
#[derive(Debug, Clone, PartialEq)]
struct Row {
    /// The count N of the non-emitting surfaces facing R: the weight of a source that is not
    /// among them (none faces R at the document's level, so no link comes from it anyway).
    count: f64,
    /// Σ_S F / max_S F: the weight of the largest source.
    largest: f64,
    /// (S, w_RS) for each facing non-emitting S, by S.
    sources: Vec<(u32, f64)>,
}

impl Row {
    /// The weights from the form factors F(R → S) of the facing non-emitting surfaces.
    fn of(f: &[(u32, f64)]) -> Row {
        let count = (f.len() as f64).max(1.0);
        let sum: f64 = f.iter().map(|x| x.1).sum();
        let largest = f.iter().map(|x| x.1).fold(0.0, f64::max);
        let weight = |fs: f64| {
            if fs > 0.0 {
                (sum / fs).clamp(1.0, count)
            } else {
                count
            }
        };
        Row {
            count,
            largest: weight(largest),
            sources: f.iter().map(|&(s, fs)| (s, weight(fs))).collect(),
        }
    }
}

/// The oracle's weights for inter-reflected light: w_RS for a receiver patch and a source
/// patch, by their document surfaces (a mesh is one).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Weights {
    /// The document surface of each patch.
    of: Vec<u32>,
    rows: Vec<Row>,
}

impl Weights {
    /// w_RS of a link from patch `s` to patch `r`: 1 / max(F_RS / Σ F_R, 1 / N_R).
    pub(super) fn between(&self, r: usize, s: usize) -> f64 {
        let row = &self.rows[self.of[r] as usize];
        let s = self.of[s];
        row.sources
            .binary_search_by_key(&s, |x| x.0)
            .map_or(row.count, |i| row.sources[i].1)
    }

    /// The weight of the largest source of patch `r`'s surface, Σ F / max F: what a link
    /// from a cluster, which may hold many surfaces, is held to.
    pub(super) fn largest(&self, r: usize) -> f64 {
        self.rows[self.of[r] as usize].largest
    }
}

/// [`SAMPLES`] points of a surface with their normals: an 8 × 8 grid of cell centres on a
/// surface of one patch (folded into a triangle's half), else the centroids of patches taken
/// at equal steps of the cumulative area.
fn receiver_points(geo: &Geometry, group: &[u32]) -> Vec<(V3, V3)> {
    if let [p] = group {
        let q = &geo.quads[*p as usize];
        let side = (SAMPLES as f64).sqrt() as usize;
        return (0..side * side)
            .map(|i| {
                let (mut u, mut v) = (
                    ((i % side) as f64 + 0.5) / side as f64,
                    ((i / side) as f64 + 0.5) / side as f64,
                );
                if q.tri && u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                (q.at(u, v), q.n)
            })
            .collect();
    }
    by_area(geo, group)
        .into_iter()
        .map(|(p, _)| {
            let q = &geo.quads[p as usize];
            let c = if q.tri { 1.0 / 3.0 } else { 0.5 };
            (q.at(c, c), q.n)
        })
        .collect()
}

/// A patch of a source surface in the sampled form factors: its corners, its normal, and the
/// share of the surface's area it stands for, over its own.
struct SourcePiece {
    corners: [V3; 4],
    normal: V3,
    weight: f64,
}

/// The patches of a source surface with the area each stands for: all of them with their own
/// when there are at most [`SAMPLES`], else [`SAMPLES`] taken at equal steps of the cumulative
/// area, each for a [`SAMPLES`]th of the whole.
fn source_pieces(geo: &Geometry, group: &[u32]) -> Vec<SourcePiece> {
    let piece = |p: u32, weight: f64| SourcePiece {
        corners: Piece::whole(p as usize).corners(&geo.quads),
        normal: geo.quads[p as usize].n,
        weight,
    };
    if group.len() <= SAMPLES {
        return group.iter().map(|&p| piece(p, 1.0)).collect();
    }
    let total: f64 = group.iter().map(|&p| geo.quads[p as usize].area).sum();
    by_area(geo, group)
        .into_iter()
        .map(|(p, area)| piece(p, total / SAMPLES as f64 / area))
        .collect()
}

/// [`SAMPLES`] patches of a surface, at equal steps of its cumulative area, with their areas.
fn by_area(geo: &Geometry, group: &[u32]) -> Vec<(u32, f64)> {
    let total: f64 = group.iter().map(|&p| geo.quads[p as usize].area).sum();
    let mut out = Vec::with_capacity(SAMPLES);
    let mut reached = 0.0;
    for &p in group {
        let area = geo.quads[p as usize].area;
        reached += area;
        while out.len() < SAMPLES && (out.len() as f64 + 0.5) / SAMPLES as f64 * total <= reached {
            out.push((p, area));
        }
    }
    out
}

/// The mean over `points` of the unoccluded form factor to the weighted `pieces`: of each
/// piece only the front, which alone sends light (the closed form counts the solid angle of
/// either side, and a closed mesh's far half, or a surface seen from behind its plane, would
/// count as much as what faces the point).
fn form_factor(points: &[(V3, V3)], pieces: &[SourcePiece]) -> f64 {
    let sum: f64 = points
        .iter()
        .map(|&(x, n)| {
            pieces
                .iter()
                .filter(|p| dot(p.normal, sub(x, p.corners[0])) > 0.0)
                .map(|p| p.weight * point_polygon(x, n, &p.corners))
                .sum::<f64>()
        })
        .sum();
    sum / points.len().max(1) as f64
}

impl Hierarchy<'_> {
    /// The oracle's tolerance for receiver `r`: ε times the brightest emission, times the
    /// share of a dim receiver (rule 2 of the module's doc): the least over the channels that
    /// its surface reflects of its mean B over the typical B, within [`Rules::dim_share`] and
    /// 1 (1 before the first solve).
    pub(super) fn tolerance(&self, r: u32) -> f64 {
        let el = &self.elements[r as usize];
        let reflectance = self.quads[el.piece.surface].material.reflectance;
        let mut share: f64 = 1.0;
        for c in 0..3 {
            if self.typical[c] > 0.0 && reflectance[c] > 0.0 {
                share = share.min(el.b[0][c] / el.area.sqrt() / self.typical[c]);
            }
        }
        self.threshold * share.clamp(self.rules.dim_share, 1.0)
    }

    /// Per channel, the area-weighted mean B over the non-emitting surfaces (0 when there are
    /// none; only E before the first solve, which is 0 there).
    pub(super) fn typical_radiosity(&self) -> [f64; 3] {
        let (mut sum, mut area) = ([0.0; 3], 0.0);
        for (i, q) in self.quads.iter().enumerate() {
            if q.material.emission.iter().all(|&e| e == 0.0) {
                let root = &self.elements[i];
                for (s, b) in sum.iter_mut().zip(root.b[0]) {
                    *s += b * root.area.sqrt();
                }
                area += root.area;
            }
        }
        if area > 0.0 {
            sum.map(|s| s / area)
        } else {
            [0.0; 3]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::three_d::hierarchy::refine::tests::cube;
    use crate::three_d::hierarchy::surface_groups;
    use crate::three_d::hierarchy::tests::{at_defaults, patches};

    /// The form factors of a unit cube's faces in closed form (Howell's catalogue, C-14 and
    /// C-11): to the opposite face and to an adjacent one.
    const OPPOSITE: f64 = 0.199_825;
    const ADJACENT: f64 = 0.200_044;

    /// The sampled form factors of w_RS against the closed forms, within the midpoint rule's
    /// error on 64 points (well under 1 %), and the weights from them: in a closed cube with
    /// an emitting ceiling, the floor sees four equal walls (w = 4 each) and the ceiling the
    /// floor and four walls, each as large as the largest (4 + 0.19982 / 0.20004).
    #[test]
    fn the_indirect_weight_shares_the_tolerance_by_form_factor_and_count() {
        let quads = &cube();
        let geo = Geometry::new(quads);
        let groups = surface_groups(quads);
        let points = receiver_points(&geo, &groups[0]);
        assert_eq!(points.len(), SAMPLES);
        let to = |b: usize| form_factor(&points, &source_pieces(&geo, &groups[b]));
        assert!((to(1) / OPPOSITE - 1.0).abs() < 0.01, "{}", to(1));
        for wall in 2..6 {
            assert!((to(wall) / ADJACENT - 1.0).abs() < 0.01, "{}", to(wall));
        }
        let w = indirect_weights(&geo, quads, &groups);
        // the floor: four equal walls, each a quarter (the ceiling emits)
        assert!((w.largest(0) - 4.0).abs() < 1e-9, "{w:?}");
        (2..6).for_each(|wall| assert!((w.between(0, wall) - 4.0).abs() < 1e-9, "{w:?}"));
        // the ceiling: four walls as large as the largest and the floor as large within the
        // sampling's error, so about a fifth each (a share of the form factor, or the count)
        assert!(
            (w.largest(1) - (4.0 + OPPOSITE / ADJACENT)).abs() < 0.02,
            "{w:?}"
        );
        assert!((w.between(1, 0) - 5.0).abs() < 0.05, "{w:?}");
        let h = at_defaults(&geo, quads);
        assert_eq!(h.indirect, w);
    }

    /// A closed convex mesh sends light only from the faces that look at a point, and every
    /// line through it crosses it twice: from a point with the whole mesh in front of it, the
    /// form factor of its front is half the solid angle that the closed form gives for all of
    /// its faces, either side counted (which is what the sampled form factor was before it
    /// left out the faces seen from behind); and a square seen only from behind sends nothing.
    #[test]
    fn a_closed_mesh_sends_from_the_faces_that_look_at_the_point() {
        // a unit cube of 12 outward triangles standing 1 unit above a 4 × 4 floor
        let positions: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                let b = |k: u32| f64::from((i >> k) & 1);
                [1.0 + b(0), 1.0 + b(1), 1.0 + b(2)]
            })
            .collect();
        let faces = [
            [0, 4, 6, 2], // x = 1
            [1, 3, 7, 5], // x = 2
            [0, 1, 5, 4], // y = 1, toward the floor
            [2, 6, 7, 3], // y = 2
            [0, 2, 3, 1], // z = 1
            [4, 5, 7, 6], // z = 2
        ];
        let triangles: Vec<[usize; 3]> = faces
            .iter()
            .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
            .collect();
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "floor", "corners": [[0, 0, 0], [0, 0, 4], [4, 0, 4], [4, 0, 0]],
             "reflectance": 0.5},
            {"name": "box", "mesh": {"positions": positions, "triangles": triangles},
             "reflectance": 0.5},
            {"name": "light", "corners": [[0, 3, 0], [4, 3, 0], [4, 3, 4], [0, 3, 4]],
             "reflectance": 0.0, "emission": 1.0},
            {"name": "turned away", "corners": [[1, 0.5, 1], [1, 0.5, 2], [2, 0.5, 2], [2, 0.5, 1]],
             "reflectance": 0.5}]},
            "solver": {"method": "hierarchical"}});
        let quads = patches(&doc);
        let geo = Geometry::new(&quads);
        let centre = [1.5, 1.5, 1.5];
        for q in &geo.quads[1..13] {
            let c = q.at(1.0 / 3.0, 1.0 / 3.0);
            assert!(dot(q.n, sub(c, centre)) > 0.0, "outward");
        }
        let groups = surface_groups(&quads);
        let points = receiver_points(&geo, &groups[0]);
        let pieces = source_pieces(&geo, &groups[1]);
        assert_eq!(pieces.len(), 12);
        let front = form_factor(&points, &pieces);
        let either_side: f64 = points
            .iter()
            .map(|&(x, n)| {
                pieces
                    .iter()
                    .map(|p| point_polygon(x, n, &p.corners))
                    .sum::<f64>()
            })
            .sum::<f64>()
            / points.len() as f64;
        assert!(front > 0.01, "{front}");
        assert!(
            (front - 0.5 * either_side).abs() < 1e-12,
            "{front} against {either_side}"
        );
        // a square above the floor that faces up shows the floor only its back
        let away = source_pieces(&geo, &groups[3]);
        let (x, n) = points[27];
        assert!(point_polygon(x, n, &away[0].corners) > 0.1);
        assert_eq!(form_factor(&points, &away), 0.0);
    }

    /// One large source close by and a small one far away: the large one's weight is 1 plus
    /// the small one's share of its form factor, not 2 as a count of the sources would have
    /// it; the small one's is the count, 2.
    /// A unit square a quarter below another (F = 0.63204 in closed form, Howell C-11; the
    /// midpoint rule on 64 points is within 1 % of it at that distance) and a 0.1-square 10
    /// away (F ≈ a / (π d²) = 3.2e-5).
    #[test]
    fn a_receiver_close_to_one_large_source_is_held_to_about_the_whole_tolerance() {
        let face = |name: &str, c: [[f64; 3]; 4]| serde_json::json!({"name": name, "corners": c, "reflectance": 0.5});
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            face("receiver", [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]),
            face("near", [[0., 0., 0.25], [0., 1., 0.25], [1., 1., 0.25], [1., 0., 0.25]]),
            face("far", [[0.45, 0.45, 10.0], [0.45, 0.55, 10.0], [0.55, 0.55, 10.0], [0.55, 0.45, 10.0]]),
            // a light, which w_R leaves out, facing away below the receiver
            {"name": "light", "corners": [[0., 0., -1.], [0., 1., -1.], [1., 1., -1.], [1., 0., -1.]], "reflectance": 0.0, "emission": 1.0},
        ]}});
        let quads = &crate::three_d::hierarchy::tests::patches(&doc);
        let geo = Geometry::new(quads);
        let groups = surface_groups(quads);
        let near = form_factor(
            &receiver_points(&geo, &groups[0]),
            &source_pieces(&geo, &groups[1]),
        );
        assert!((near / 0.63204 - 1.0).abs() < 0.01, "{near}");
        let w = indirect_weights(&geo, quads, &groups);
        assert!(w.largest(0) > 1.0 && w.largest(0) < 1.0 + 1e-4, "{w:?}");
        assert_eq!(w.between(0, 1), w.largest(0));
        // the far one gets an equal share of the two, not its 5e-5 of the form factor
        assert_eq!(w.between(0, 2), 2.0);
    }

    /// The shares 1 / w_RS of a receiver's sources add up to at least 1 and at most 2,
    /// whatever the form factors (here 200 draws of 1 to 60 sources over nine decades), so
    /// that the errors of the links into a receiver stay within twice its tolerance; the
    /// largest source's weight is Σ F / max F, and no weight is above the count.
    #[test]
    fn the_sources_shares_of_a_receivers_tolerance_add_up_to_at_most_two() {
        let mut rng = crate::three_d::visibility::SplitMix(5);
        for _ in 0..200 {
            let n = 1 + (rng.next_u64() % 60) as u32;
            let f: Vec<(u32, f64)> = (0..n)
                .map(|s| (s, 10f64.powf(-9.0 * rng.next_f64())))
                .collect();
            let row = Row::of(&f);
            let shares: f64 = row.sources.iter().map(|x| 1.0 / x.1).sum();
            assert!(
                (1.0 - 1e-12..=2.0 + 1e-12).contains(&shares),
                "{shares} {row:?}"
            );
            let (sum, max) = f
                .iter()
                .fold((0.0, 0.0f64), |(a, m), x| (a + x.1, m.max(x.1)));
            assert!((row.largest - (sum / max).min(n as f64)).abs() < 1e-9 * row.largest);
            assert!(row.sources.iter().all(|x| x.1 >= 1.0 && x.1 <= n as f64));
        }
    }

    /// The tolerance is ε times the brightest emission; after a solve, a receiver dimmer than
    /// the typical B in a channel it reflects gets the ratio, the least over the channels,
    /// down to [`Rules::dim_share`]; a channel it does not reflect does not count; and it is the
    /// element's own B that counts, not its surface's.
    #[test]
    fn a_dim_receiver_gets_its_share_of_the_typical_radiosity() {
        let mut quads = cube();
        quads[2].material.reflectance = [0.0, 0.5, 0.5];
        let geo = Geometry::new(&quads);
        let mut h = at_defaults(&geo, &quads);
        assert_eq!(h.tolerance(0), 1e-3);
        let set = |h: &mut Hierarchy, i: usize, b: [f64; 3]| {
            let a = h.elements[i].area;
            h.elements[i].b[0] = b.map(|v| v * a.sqrt());
        };
        // the floor at B = ½ in red and 2 in green and blue, the south wall at ¼ in red, the
        // other walls at 2: typical red (½ + ¼ + 3 · 2) / 5 = 1.35, the others 2
        set(&mut h, 0, [0.5, 2.0, 2.0]);
        set(&mut h, 2, [0.25, 2.0, 2.0]);
        (3..6).for_each(|i| set(&mut h, i, [2.0; 3]));
        h.typical = h.typical_radiosity();
        assert!((h.typical[0] - 1.35).abs() < 1e-12 && (h.typical[1] - 2.0).abs() < 1e-12);
        assert!((h.tolerance(0) - 1e-3 * 0.5 / 1.35).abs() < 1e-15);
        // the south wall reflects no red
        assert_eq!(h.tolerance(2), 1e-3);
        assert_eq!(h.tolerance(3), 1e-3);
        set(&mut h, 0, [0.01, 2.0, 2.0]);
        h.typical = h.typical_radiosity();
        assert_eq!(h.tolerance(0), 1e-3 * h.rules.dim_share);
        // a child of the bright north wall lying in a shadow, at a quarter of the typical
        let child = h.split(3);
        let typical = h.typical;
        let a = h.elements[child as usize].area;
        h.elements[child as usize].b[0] = typical.map(|t| 0.25 * t * a.sqrt());
        assert!((h.tolerance(child) - 0.25e-3).abs() < 1e-15);
        assert_eq!(h.tolerance(child + 1), 1e-3);
    }
}

//! Geometry that the format allows but that cannot be physically right: flatland segments
//! that cross, collinear segments that overlap, 3d surfaces that pass through each other and
//! coplanar surfaces that overlap, and 3d surfaces on whose back (black: a surface receives and
//! sends light on its front only) much of the emitters' light lands, which is how faces that
//! point the wrong way show. The job still runs (the scene is valid); the result lists each
//! case as a [`Warning`] with the JSON paths of the surfaces involved.
//!
//! Touching is not a warning: segments that meet at an end, a wall that stands on a floor or
//! meets another along an edge, surfaces that share a corner. Nor are two surfaces back to
//! back in one place: that is how a two-sided thin wall is made (`flatland-occluded.json`).

use crate::result::Warning;
use crate::scene::{Job, Quad, SceneKind, Segment};

/// The warnings of a job's geometry, pairs in document order (i < j).
pub fn geometry(job: &Job) -> Vec<Warning> {
    match &job.scene.kind {
        SceneKind::Flatland(segments) => flatland(segments),
        SceneKind::ThreeD(d) => three_d(d),
        SceneKind::Fredholm(_) => Vec::new(),
    }
}

fn path(i: usize) -> String {
    format!("/scene/surfaces/{i}")
}

fn warning(i: usize, j: usize, message: String) -> Warning {
    Warning {
        paths: vec![path(i), path(j)],
        message,
    }
}

/// The size of a scene: the largest absolute coordinate (at least a tiny positive number),
/// against which the tolerances are taken.
fn scale<'a>(coords: impl Iterator<Item = &'a f64>) -> f64 {
    coords.fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300)
}

fn flatland(segments: &[Segment]) -> Vec<Warning> {
    let size = scale(segments.iter().flat_map(|s| s.a.iter().chain(&s.b)));
    let eps = 1e-9 * size;
    let mut out = Vec::new();
    for i in 0..segments.len() {
        for j in i + 1..segments.len() {
            if let Some(message) = segment_pair(&segments[i], &segments[j], eps) {
                out.push(warning(i, j, message));
            }
        }
    }
    out
}

fn cross2(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn sub2(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn segment_pair(s: &Segment, t: &Segment, eps: f64) -> Option<String> {
    let d = sub2(s.b, s.a);
    let e = sub2(t.b, t.a);
    let (ld, le) = (d[0].hypot(d[1]), e[0].hypot(e[1]));
    let denom = cross2(d, e);
    let w = sub2(t.a, s.a);
    if denom.abs() > 1e-12 * ld * le {
        // p = s.a + u d = t.a + v e
        let u = cross2(w, e) / denom;
        let v = cross2(w, d) / denom;
        // strictly inside both, by more than eps in length: meeting at an end is touching
        let inside = |x: f64, len: f64| x * len > eps && (1.0 - x) * len > eps;
        if inside(u, ld) && inside(v, le) {
            let p = [s.a[0] + u * d[0], s.a[1] + u * d[1]];
            return Some(format!(
                "surfaces \"{}\" and \"{}\" cross at ({}, {}): each occludes the other's light on one side",
                s.name,
                t.name,
                short(p[0]),
                short(p[1])
            ));
        }
        return None;
    }
    // parallel: on one line when t.a is on s's line
    if cross2(d, w).abs() > eps * ld {
        return None;
    }
    // overlap of the parameter intervals along d
    let along = |p: [f64; 2]| (sub2(p, s.a)[0] * d[0] + sub2(p, s.a)[1] * d[1]) / ld;
    let (t0, t1) = {
        let (x, y) = (along(t.a), along(t.b));
        (x.min(y), x.max(y))
    };
    let overlap = t1.min(ld) - t0.max(0.0);
    // back to back is a two-sided thin wall, each side one surface: only the same front twice
    // is a warning
    if overlap > eps && d[0] * e[0] + d[1] * e[1] > 0.0 {
        return Some(format!(
            "surfaces \"{}\" and \"{}\" lie on one line, facing the same way, and overlap over a length of {}: which of them is seen there is undefined",
            s.name,
            t.name,
            short(overlap)
        ));
    }
    None
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

fn unit(a: V3) -> V3 {
    let n = norm(a);
    [a[0] / n, a[1] / n, a[2] / n]
}

/// The corners of a parallelogram in order around it (p0, p1, p2, p3).
fn polygon(q: &Quad) -> [V3; 4] {
    q.corners
}

fn normal(q: &Quad) -> V3 {
    let c = &q.corners;
    unit(cross(sub(c[1], c[0]), sub(c[3], c[0])))
}

/// Pairs of parallelograms (the checks are not made for triangles and meshes yet).
fn three_d(d: &crate::scene::ThreeD) -> Vec<Warning> {
    let quads = &d.patches;
    let owners = d.owners();
    let size = scale(quads.iter().flat_map(|q| q.corners.iter().flatten()));
    let eps = 1e-9 * size;
    let mut out = backlit(d);
    // (the parallelograms among the patches only: a mesh has as many patches as triangles)
    let parallelograms: Vec<usize> = (0..quads.len()).filter(|&i| !quads[i].triangle).collect();
    for (a, &i) in parallelograms.iter().enumerate() {
        for &j in &parallelograms[a + 1..] {
            if let Some(message) = quad_pair(&quads[i], &quads[j], eps) {
                out.push(warning(owners[i], owners[j], message));
            }
        }
    }
    out
}

/// Rays cast from the emitters by [`backlit`].
const BACKLIT_RAYS: usize = 4096;

/// The share of the emitters' rays whose first hit on the back of one surface makes it a
/// warning: 1 % of the emitted light lost at its first bounce.
const BACKLIT_SHARE: f64 = 0.01;

/// The surfaces on whose back at least [`BACKLIT_SHARE`] of the emitted light first lands.
/// [`BACKLIT_RAYS`] rays leave the emitting patches in proportion to their power (stratified
/// over the patches, at a point of the emission region, in a cosine-distributed direction)
/// and the nearest hit of each is found through the scene's BVH: a ray that meets a surface
/// from behind (its direction along the surface's normal) is light that the solve absorbs
/// there. In a closed room of well-made solids no ray does; a box whose faces point inward
/// takes the light that falls on it (a model with flipped normals: the first thing to check
/// when an imported scene comes out dark). The estimate is a fraction of n rays, within
/// √(p(1 − p)/n) ≤ 0.8 % of the true share.
fn backlit(d: &crate::scene::ThreeD) -> Vec<Warning> {
    use crate::three_d::bvh::Bvh;
    use crate::three_d::cover::covered_at;
    use crate::three_d::geometry::{add, cross, dot, normalize, scale, Parallelogram};
    let quads: Vec<Parallelogram> = d.patches.iter().map(Parallelogram::of).collect();
    let power: Vec<f64> = d
        .patches
        .iter()
        .zip(&quads)
        .map(|(q, p)| {
            let (rs, rt) = q.emission_region;
            let e = q.material.emission.iter().sum::<f64>() / 3.0;
            let region = if q.triangle {
                1.0
            } else {
                (rs[1] - rs[0]) * (rt[1] - rt[0])
            };
            e.max(0.0) * region * p.area
        })
        .collect();
    let total: f64 = power.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    let bvh = Bvh::new(&quads);
    let owners = d.owners();
    let mut back = vec![0usize; d.surfaces.len()];
    let mut sent = BACKLIT_RAYS;
    let (mut patch, mut below) = (0, 0.0);
    for i in 0..BACKLIT_RAYS {
        // the i-th ray's patch: stratified over the cumulative power
        let at = (i as f64 + 0.5) / BACKLIT_RAYS as f64 * total;
        while patch + 1 < power.len() && below + power[patch] <= at {
            below += power[patch];
            patch += 1;
        }
        let (q, p) = (&d.patches[patch], &quads[patch]);
        // a point of the emission region and a direction from a 4-dimensional
        // low-discrepancy sequence (Roberts' R₄: fractional parts of multiples of the powers
        // of the inverse of the root of x⁵ = x + 1)
        let [a, b, c, e] = r4(i);
        let (rs, rt) = q.emission_region;
        let (mut s, mut t) = (rs[0] + a * (rs[1] - rs[0]), rt[0] + b * (rt[1] - rt[0]));
        if q.triangle && s + t > 1.0 {
            (s, t) = (1.0 - s, 1.0 - t);
        }
        let helper = if p.n[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let x = normalize(cross(p.n, helper));
        let y = cross(p.n, x);
        let (r, phi) = (c.sqrt(), std::f64::consts::TAU * e);
        let dir = add(
            add(scale(x, r * phi.cos()), scale(y, r * phi.sin())),
            scale(p.n, (1.0 - c).sqrt()),
        );
        if let Some(hit) = bvh.first_hit(p.at(s, t), dir, 0.0, f64::INFINITY, [patch, patch]) {
            if dot(dir, quads[hit.surface].n) > 0.0 {
                // from where a solid stands on the emitter (a window's bar on its pane) no
                // light leaves ([`crate::three_d::cover`]): not a ray of the emitted light
                if covered_at(&quads, &bvh, patch, s, t) {
                    sent -= 1;
                } else {
                    back[owners[hit.surface]] += 1;
                }
            }
        }
    }
    back.iter()
        .enumerate()
        .filter(|&(_, &n)| n > 0 && n as f64 >= BACKLIT_SHARE * sent as f64)
        .map(|(i, &n)| Warning {
            paths: vec![path(i)],
            message: format!(
                "{:.1} % of the light that leaves the emitters first lands on the back of surface \"{}\", which is black (a surface receives and sends light on its front only, the side its corners go counter-clockwise around): do its faces point the wrong way?",
                100.0 * n as f64 / sent as f64,
                d.surfaces[i].name
            ),
        })
        .collect()
}

/// The i-th point of Roberts' R₄ sequence in [0, 1)⁴.
fn r4(i: usize) -> [f64; 4] {
    // g: the real root of x⁵ = x + 1
    const G: f64 = 1.167_303_978_261_418_7;
    let mut out = [0.0; 4];
    let mut a = 1.0;
    for o in &mut out {
        a /= G;
        *o = (0.5 + a * (i + 1) as f64).fract();
    }
    out
}

fn quad_pair(a: &Quad, b: &Quad, eps: f64) -> Option<String> {
    let (pa, pb) = (polygon(a), polygon(b));
    let (na, nb) = (normal(a), normal(b));
    let dist_to = |n: V3, origin: V3, p: V3| dot(n, sub(p, origin));
    let da: Vec<f64> = pb.iter().map(|&p| dist_to(na, pa[0], p)).collect();
    let db: Vec<f64> = pa.iter().map(|&p| dist_to(nb, pb[0], p)).collect();
    let line = cross(na, nb);
    if norm(line) < 1e-9 {
        // parallel planes: coplanar when b's corners lie in a's plane
        if da.iter().any(|d| d.abs() > eps) {
            return None;
        }
        // back to back is a two-sided thin wall, each side one surface
        if dot(na, nb) < 0.0 {
            return None;
        }
        let area = coplanar_overlap(&pa, &pb, na);
        let smaller = norm(cross(sub(pa[1], pa[0]), sub(pa[3], pa[0])))
            .min(norm(cross(sub(pb[1], pb[0]), sub(pb[3], pb[0]))));
        if area > 1e-9 * smaller {
            return Some(format!(
                "surfaces \"{}\" and \"{}\" lie in one plane, facing the same way, and overlap over an area of {}: which of them is seen there is undefined",
                a.name,
                b.name,
                short(area)
            ));
        }
        return None;
    }
    // each must have corners strictly on both sides of the other's plane
    let both_sides = |d: &[f64]| d.iter().any(|&x| x > eps) && d.iter().any(|&x| x < -eps);
    if !both_sides(&da) || !both_sides(&db) {
        return None;
    }
    let line = unit(line);
    let ia = plane_cut(&pa, &db, line)?;
    let ib = plane_cut(&pb, &da, line)?;
    let lo = ia.0.max(ib.0);
    let hi = ia.1.min(ib.1);
    if hi - lo > eps {
        // a point of the common segment, for the message
        let from = if ia.0 >= ib.0 { ia.2 } else { ib.2 };
        let mid = [
            from[0] + line[0] * (hi - lo) / 2.0,
            from[1] + line[1] * (hi - lo) / 2.0,
            from[2] + line[2] * (hi - lo) / 2.0,
        ];
        return Some(format!(
            "surfaces \"{}\" and \"{}\" pass through each other along a segment of length {} through ({}, {}, {}): light leaks through where they cross",
            a.name,
            b.name,
            short(hi - lo),
            short(mid[0]),
            short(mid[1]),
            short(mid[2])
        ));
    }
    None
}

/// Where the other plane cuts a convex polygon whose corners are at signed distances `d` from
/// it: the interval of the cut along `line` (positions as dot products with it) and the point
/// of the cut at its lower end.
fn plane_cut(poly: &[V3; 4], d: &[f64], line: V3) -> Option<(f64, f64, V3)> {
    let mut lo: Option<(f64, V3)> = None;
    let mut hi: Option<f64> = None;
    let mut add = |p: V3| {
        let t = dot(p, line);
        if lo.is_none_or(|(l, _)| t < l) {
            lo = Some((t, p));
        }
        if hi.is_none_or(|h| t > h) {
            hi = Some(t);
        }
    };
    for k in 0..4 {
        let (p, q) = (poly[k], poly[(k + 1) % 4]);
        let (dp, dq) = (d[k], d[(k + 1) % 4]);
        if dp == 0.0 {
            add(p);
        }
        if (dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0) {
            let s = dp / (dp - dq);
            add([
                p[0] + s * (q[0] - p[0]),
                p[1] + s * (q[1] - p[1]),
                p[2] + s * (q[2] - p[2]),
            ]);
        }
    }
    let (l, p) = lo?;
    Some((l, hi?, p))
}

/// The area of the overlap of two convex polygons in one plane (normal `n`).
fn coplanar_overlap(a: &[V3; 4], b: &[V3; 4], n: V3) -> f64 {
    // 2D coordinates in the plane
    let u = unit(sub(a[1], a[0]));
    let v = cross(n, u);
    let flat = |p: V3| [dot(sub(p, a[0]), u), dot(sub(p, a[0]), v)];
    let ccw = |poly: &[V3; 4]| {
        let mut pts: Vec<[f64; 2]> = poly.iter().map(|&p| flat(p)).collect();
        if signed_area(&pts) < 0.0 {
            pts.reverse();
        }
        pts
    };
    let clip = ccw(b);
    let mut subject = ccw(a);
    for k in 0..clip.len() {
        let (c0, c1) = (clip[k], clip[(k + 1) % clip.len()]);
        let edge = sub2(c1, c0);
        let side = |p: [f64; 2]| cross2(edge, sub2(p, c0));
        let mut next = Vec::with_capacity(subject.len() + 2);
        for m in 0..subject.len() {
            let (p, q) = (subject[m], subject[(m + 1) % subject.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                next.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let s = sp / (sp - sq);
                next.push([p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])]);
            }
        }
        subject = next;
        if subject.len() < 3 {
            return 0.0;
        }
    }
    signed_area(&subject).abs()
}

fn signed_area(pts: &[[f64; 2]]) -> f64 {
    let mut s = 0.0;
    for k in 0..pts.len() {
        s += cross2(pts[k], pts[(k + 1) % pts.len()]);
    }
    s / 2.0
}

/// A number for a message: four significant digits, no trailing zeros.
fn short(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let digits = (3 - x.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let s = format!("{x:.digits$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

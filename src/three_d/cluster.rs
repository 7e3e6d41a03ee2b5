//! Volume clusters over the patches of a 3D scene (Smits, Arvo and Greenberg, "A Clustering
//! Algorithm for Radiosity in Complex Environments", SIGGRAPH 1994; Sillion, "A Unified
//! Hierarchical Algorithm for Global Illumination with Scattering Volumes and Object
//! Clusters", IEEE TVCG 1995).
//!
//! The hierarchical solver starts from one link of the root cluster to itself instead of a
//! link for every pair of facing patches, and splits clusters where the oracle asks, down to
//! the patches' element trees. The tree is built over each mesh's triangles and then over the
//! meshes, so that a model of many objects starts from one pair. A surface of one patch (a
//! parallelogram or a triangle) is not a member of a cluster: a cluster link gives each of
//! its receiving members one constant, at its centroid, which on a wall of a room or the face
//! of a box is too coarse for its cells (a room with 3 × 3 boxes had a cell of a box's face
//! 5.9 % off its path-traced reference with the boxes' faces in clusters). Those surfaces
//! start paired with each other and with the meshes' root, as the document names them. A link that stays between clusters carries the transfer of
//! eq. (3) from the source's members, each taken as a point at its centroid, to each member
//! of the receiver at its own centroid, every member keeping its own orientation (the
//! oriented transfer of Sillion 1995, §4). When every member of the source faces every point
//! of the receiver (`Bound::before`), the source's sum is carried by a few moments (the
//! irradiance's numerator is affine in the receiving point; [`crate::three_d::hierarchy`]'s
//! `Emitter`, expanded to second order), and the error is third order in the source's size
//! over the distance; a source that is one element sends its mean B through each member's
//! point-to-polygon form factor instead, in closed form (Baum, Rushmeier and Winget 1989),
//! exact for that mean whatever the distance; otherwise each member j of the source that
//! sends toward the receiving point x (the whole cluster where all its members face the
//! direction of x, else the parts of it that face the receiver's centre, each where its
//! weights at x are positive) weighs by what it sends there, and the sum is taken about the
//! centroid of those weights,
//!
//! ```text
//! w_j(x)   = B̄_j A_j n_j · (x − y_j)                     (J · x − K of the part's moments)
//! c(x)     = Σ_j w_j(x) y_j / Σ_j w_j(x)                  (Q x − q over the same sum)
//! H_i     += V · Σ_j w_j(x_i) · n_i · (c − x_i) / (π |c − x_i|⁴)   (each member i of R at x_i)
//! ```
//!
//! with V the visible fraction between the two ends. About c the term of first order in the
//! source's size over the distance vanishes, and each member's cosine is read at its own
//! plane: the error is second order in the source's size and first order in the receiving
//! member's. (As an intensity I(ω) = Σ_j B̄_j A_j (n_j · ω)₊ / π sent from one point, the
//! cosines were read at that point: first order, and large where a member is seen edge-on.)
//! The oracle bounds what each leaves out.
//!
//! Two clusters interact only if a point of each may be in front of a member of the other:
//! each cluster's box, the cone of its members' normals and the range of its points along the
//! cone's axis bound that (`Bound::front`). So the clusters of a planar mesh never link to
//! one another, and those of a convex one only along their shared borders.

use crate::three_d::geometry::{add, centroid, dot, norm, scale, sub, Parallelogram, V3};

/// A reference to a cluster (this bit set) or to an element of the hierarchy.
pub(super) const CLUSTER: u32 = 1 << 31;

/// The box, normal cone and slab of a set of surfaces: what the interaction tests need.
#[derive(Debug, Clone, Copy)]
pub(super) struct Bound {
    lo: V3,
    hi: V3,
    /// The axis of the normal cone (unit), and the cosine and sine of its half-angle; a cone
    /// of π/2 or more (cos ≤ 0) holds every direction that matters.
    axis: V3,
    cos: f64,
    sin: f64,
    /// The least and largest `axis · x` over the surfaces' points.
    slab: [f64; 2],
}

impl Bound {
    /// The bound of one flat polygon (corners, repeated corners allowed) with normal `n`.
    pub(super) fn of_polygon(corners: &[V3], n: V3) -> Bound {
        let (mut lo, mut hi) = (corners[0], corners[0]);
        for c in corners {
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        let along = corners.iter().map(|&c| dot(n, c));
        let slab = along.fold([f64::INFINITY, f64::NEG_INFINITY], |s, x| {
            [s[0].min(x), s[1].max(x)]
        });
        Bound {
            lo,
            hi,
            axis: n,
            cos: 1.0,
            sin: 0.0,
            slab,
        }
    }

    /// The bound of patches `members` of `quads`, weighted by area for the cone's axis.
    pub(super) fn of_patches(quads: &[Parallelogram], members: &[u32]) -> Bound {
        let mut sum = [0.0; 3];
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &m in members {
            let q = &quads[m as usize];
            sum = add(sum, scale(q.n, q.area));
            for c in q.outline() {
                for a in 0..3 {
                    lo[a] = lo[a].min(c[a]);
                    hi[a] = hi[a].max(c[a]);
                }
            }
        }
        let len = norm(sum);
        let axis = if len > 0.0 {
            scale(sum, 1.0 / len)
        } else {
            [0.0, 0.0, 1.0]
        };
        let cos = members
            .iter()
            .map(|&m| dot(axis, quads[m as usize].n))
            .fold(1.0, f64::min);
        // the sine from the cross products: from 1 − cos² it would be √(2 · rounding), and the
        // parts of one plane would seem to face each other across it
        let sin = members
            .iter()
            .map(|&m| norm(crate::three_d::geometry::cross(axis, quads[m as usize].n)))
            .fold(0.0, f64::max);
        let slab = members
            .iter()
            .flat_map(|&m| quads[m as usize].outline())
            .map(|c| dot(axis, c))
            .fold([f64::INFINITY, f64::NEG_INFINITY], |s, x| {
                [s[0].min(x), s[1].max(x)]
            });
        Bound {
            lo,
            hi,
            axis,
            cos: if len > 0.0 { cos.max(-1.0) } else { -1.0 },
            sin: sin.min(1.0),
            slab,
        }
    }

    pub(super) fn diameter(&self) -> f64 {
        norm(sub(self.hi, self.lo))
    }

    /// The sphere about the box: its centre and radius.
    pub(super) fn sphere(&self) -> (V3, f64) {
        (scale(add(self.lo, self.hi), 0.5), 0.5 * self.diameter())
    }

    /// The distance between the two boxes (0 when they meet).
    pub(super) fn distance(&self, other: &Bound) -> f64 {
        let gap = |a: usize| {
            (other.lo[a] - self.hi[a])
                .max(self.lo[a] - other.hi[a])
                .max(0.0)
        };
        norm([gap(0), gap(1), gap(2)])
    }

    /// The largest distance between a point of each box.
    fn reach(&self, other: &Bound) -> f64 {
        let far = |a: usize| (other.hi[a] - self.lo[a]).max(self.hi[a] - other.lo[a]);
        norm([far(0), far(1), far(2)])
    }

    /// The largest `d · x` over the box.
    fn support(&self, d: V3) -> f64 {
        (0..3)
            .map(|a| (d[a] * self.lo[a]).max(d[a] * self.hi[a]))
            .sum()
    }

    /// Whether a point of `other` may be strictly in front of a surface of `self`: an upper
    /// bound of n_r · (x_s − x_r) over the normals n_r of self's cone, its points x_r and the
    /// points x_s of `other` is above the rounding of the coordinates. With n_r = a cos α + p
    /// sin α (α within the cone, p ⟂ a), n_r · d ≤ max(a · d, cos θ · a · d) + sin θ |d|;
    /// a · x_s is bounded by other's slab along its own axis plus its box across it, which is
    /// exact for two parts of one plane.
    fn front(&self, other: &Bound) -> bool {
        if self.cos <= 0.0 {
            return true;
        }
        let a = self.axis;
        let c = dot(a, other.axis);
        let across = sub(a, scale(other.axis, c));
        let along = if c >= 0.0 {
            c * other.slab[1]
        } else {
            c * other.slab[0]
        };
        let m = along + other.support(across) - self.slab[0];
        let reach = self.reach(other);
        let bound = if m >= 0.0 { m } else { self.cos * m } + self.sin * reach;
        let tol = 1e-9 * (self.diameter() + other.diameter());
        bound > tol
    }

    /// Whether every point of `other` is strictly in front of every surface of `self`: a
    /// lower bound of n_s · (x_r − x_s) over self's cone, its points x_s and the points x_r of
    /// other's box is positive. With n_s = a cos α + p sin α, n_s · d ≥ cos θ · a · d − sin θ
    /// |d| when a · d ≥ 0. Then no member of `self` turns its back on any point of `other`,
    /// and the light `self` sends there is the affine sum of [`crate::three_d::hierarchy`]'s
    /// cluster links.
    pub(super) fn before(&self, other: &Bound) -> bool {
        if self.cos <= 0.0 {
            return false;
        }
        let m = -other.support(scale(self.axis, -1.0)) - self.slab[1];
        let tol = 1e-9 * (self.diameter() + other.diameter());
        m > tol && self.cos * m - self.sin * self.reach(other) > tol
    }

    /// Which side of the plane normal to the unit `omega` every normal of the set is on:
    /// `Some(true)` when n · ω > 0 for every one, `Some(false)` when n · ω < 0 for every
    /// one, `None` when the cone may hold both (always for a cone of π/2 or more). For a
    /// normal n at an angle of cosine a · n ≥ cos and sine |a × n| ≤ sin from the axis a,
    /// n · ω lies within (a · n)(a · ω) ± |a × n| |a × ω|.
    pub(super) fn side(&self, omega: V3) -> Option<bool> {
        if self.cos <= 0.0 {
            return None;
        }
        let along = dot(self.axis, omega);
        let across = (1.0 - along * along).max(0.0).sqrt();
        if along > 0.0 && self.cos * along - self.sin * across > 0.0 {
            Some(true)
        } else if along < 0.0 && self.cos * along + self.sin * across < 0.0 {
            Some(false)
        } else {
            None
        }
    }

    /// The point of the box nearest to `p` (p itself when inside).
    pub(super) fn nearest(&self, p: V3) -> V3 {
        [0, 1, 2].map(|a| p[a].clamp(self.lo[a], self.hi[a]))
    }

    /// The largest n · ω over the normal cone, for the unit `omega` (1 for a cone of π/2 or
    /// more, or one that holds ω).
    pub(super) fn largest_cosine(&self, omega: V3) -> f64 {
        if self.cos <= 0.0 {
            return 1.0;
        }
        let along = dot(self.axis, omega);
        let across = (1.0 - along * along).max(0.0).sqrt();
        // ω at an angle θ from the axis, the cone's half-angle α: cos(θ − α) where θ > α
        if along >= self.cos {
            1.0
        } else {
            along * self.cos + across * self.sin
        }
    }

    /// Whether the two sets may exchange light: each may be in front of the other.
    pub(super) fn facing(&self, other: &Bound) -> bool {
        self.front(other) && other.front(self)
    }
}

/// One cluster: a box of patches, with two children (clusters, or patches as references to
/// their root elements).
#[derive(Debug, Clone)]
pub struct Cluster {
    pub(super) bound: Bound,
    /// Its members: `order[members.0..members.1]` of [`Clusters`].
    members: (u32, u32),
    pub(super) children: [u32; 2],
    /// The sum of the members' areas.
    pub area: f64,
    /// The area-weighted centroid of its members.
    pub(super) centre: V3,
    /// The largest diameter of a member.
    pub(super) member_diameter: f64,
}

/// The cluster tree of a scene's patches.
#[derive(Debug, Clone)]
pub struct Clusters {
    pub(super) nodes: Vec<Cluster>,
    /// The patches, each cluster's members one run of them.
    order: Vec<u32>,
    /// The areas of `order` that send or receive light ([`Clusters::weigh`]) summed up to
    /// each position (one more than the patches).
    prefix: Vec<f64>,
    /// The light of `order` (the weighed area times the mean B it sends,
    /// [`Clusters::weigh_light`]) summed up likewise; empty until weighed.
    light: Vec<f64>,
    /// Each patch's place in `order`.
    position: Vec<u32>,
    /// The root of each group's tree: a cluster, or the group's only patch.
    pub(super) roots: Vec<u32>,
    /// Where the refinement starts: the patch of every surface of one patch (a parallelogram
    /// or a triangle), and the root of one tree over the meshes, each mesh's own tree a
    /// subtree of it.
    pub(super) starts: Vec<u32>,
    /// The centroid of every patch.
    pub(super) centres: Vec<V3>,
}

/// What the tree over the groups is built from: the patches, and per group its area, its
/// area-weighted centroid, its diameter and its largest patch's, each taken once.
struct Scene<'a> {
    quads: &'a [Parallelogram],
    centres: &'a [V3],
    groups: &'a [Vec<u32>],
    area: Vec<f64>,
    centre: Vec<V3>,
    diameter: Vec<f64>,
    member_diameter: Vec<f64>,
}

/// Where a cluster's items (patches, or groups of them) are halved: the largest, of
/// `largest` = (its index, its diameter), split off alone at the front when it is half the
/// box and half the area; else the items are ordered about the median of their centres
/// along the longest side of the centres' box (ties by the item) and halved there.
fn halve(
    items: &mut [u32],
    largest: (usize, f64),
    box_diameter: f64,
    total_area: f64,
    area: impl Fn(u32) -> f64,
    centre: impl Fn(u32) -> V3,
) -> usize {
    let (big, size) = largest;
    if size >= PEEL * box_diameter && area(items[big]) >= PEEL * total_area {
        items.swap(0, big);
        return 1;
    }
    at_median(items, centre)
}

/// Halves `items` by their normals: ordered along the axis on which the normals spread the
/// most (ties by the item), at the median. Repeated while a half's members face opposite
/// ways, it leaves clusters whose normals lie within a hemisphere, the faces of a box one
/// side or two adjacent sides to a cluster.
fn facing_halves(items: &mut [u32], normal: impl Fn(u32) -> V3) -> usize {
    at_median(items, normal)
}

/// Orders `items` about the median of `key` along the axis on which the keys' box is
/// longest (ties by the item) and returns the median's index: the halving of [`halve`] (by
/// centre) and of [`facing_halves`] (by normal).
fn at_median(items: &mut [u32], key: impl Fn(u32) -> V3) -> usize {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &m in items.iter() {
        let c = key(m);
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |&a, &b| {
        key(a)[axis].total_cmp(&key(b)[axis]).then(a.cmp(&b))
    });
    mid
}

/// The index and value of the first largest of `values`.
fn largest(values: impl Iterator<Item = f64>) -> (usize, f64) {
    values
        .enumerate()
        .fold((0, 0.0), |b, x| if x.1 > b.1 { x } else { b })
}

/// A member with at least this share of its cluster's diameter and of its area is a child
/// of its own: a wall in a cluster of small objects would keep the cluster as large as the
/// room. (The share of the area keeps a cluster of long, thin triangles from being peeled one
/// by one into a chain.)
const PEEL: f64 = 0.5;

impl Clusters {
    /// A tree over each group of `quads` (the patches of one mesh): from the top, members that
    /// face opposite ways (a normal cone of a hemisphere or more) are halved by their normals
    /// ([`facing_halves`]); else a member as large as half the box is split off alone, else
    /// the members are halved at the median of their centroids along the longest side of the
    /// centroids' box (O(P log P)).
    ///
    /// Normals first, as in face cluster radiosity (Willmott, Heckbert and Garland, "Face
    /// Cluster Radiosity", EGWR 1999): a link gives every member of its receiving cluster one
    /// visible fraction, which is right only for members that see its source alike. Halved in
    /// space, a row of books made one cluster of faces toward the room, tops, and faces in the
    /// 3 mm slits between them; a furnace (B = 2 everywhere) put the first at 1.76 and the last
    /// at 2.04 (`tests/meshes.rs`, `a_row_of_books_keeps_the_furnace_on_every_side`).
    pub(super) fn new(quads: &[Parallelogram], groups: &[Vec<u32>]) -> Clusters {
        let centres: Vec<V3> = quads
            .iter()
            .map(|q| centroid(&q.outline(), q.tri))
            .collect();
        let mut tree = Clusters {
            nodes: Vec::new(),
            order: Vec::new(),
            prefix: vec![0.0],
            light: Vec::new(),
            position: Vec::new(),
            roots: Vec::new(),
            starts: Vec::new(),
            centres: Vec::new(),
        };
        let mut order = vec![0; groups.iter().map(Vec::len).sum()];
        tree.roots = vec![0; groups.len()];
        // surfaces of one patch first, each its own root; then the meshes under one tree
        let (mut meshes, singles): (Vec<u32>, Vec<u32>) =
            (0..groups.len() as u32).partition(|&g| groups[g as usize].len() > 1);
        for (k, &g) in singles.iter().enumerate() {
            let g = g as usize;
            order[k] = groups[g][0];
            tree.roots[g] = groups[g][0];
            tree.starts.push(groups[g][0]);
        }
        if !meshes.is_empty() {
            let area: Vec<f64> = groups
                .iter()
                .map(|g| g.iter().map(|&m| quads[m as usize].area).sum())
                .collect();
            let scene = Scene {
                quads,
                centres: &centres,
                groups,
                centre: groups
                    .iter()
                    .zip(&area)
                    .map(|(g, a)| {
                        let sum = g.iter().fold([0.0; 3], |s, &m| {
                            add(s, scale(centres[m as usize], quads[m as usize].area))
                        });
                        scale(sum, 1.0 / a)
                    })
                    .collect(),
                diameter: groups
                    .iter()
                    .map(|g| Bound::of_patches(quads, g).diameter())
                    .collect(),
                member_diameter: groups
                    .iter()
                    .map(|g| {
                        g.iter()
                            .map(|&m| quads[m as usize].diameter())
                            .fold(0.0, f64::max)
                    })
                    .collect(),
                area,
            };
            let top = tree.build_top(&scene, &mut meshes, &mut order, singles.len() as u32);
            tree.starts.push(top);
        }
        tree.position = vec![0; quads.len()];
        for (k, &p) in order.iter().enumerate() {
            tree.position[p as usize] = k as u32;
        }
        tree.order = order;
        tree.centres = centres;
        tree.weigh(quads, |_| 1.0);
        tree
    }

    /// The tree over groups `ids` (their patches laid out in `order` from `start`): one
    /// group is its own tree ([`Clusters::build`]); more are halved as the patches of one
    /// are, a group as large as half the box and half the area split off alone (a room's
    /// floor), else the groups halved at the median of their centroids along the longest
    /// side of the centroids' box.
    fn build_top(&mut self, scene: &Scene, ids: &mut [u32], order: &mut [u32], start: u32) -> u32 {
        let (quads, groups) = (scene.quads, scene.groups);
        if let [g] = ids {
            let g = *g as usize;
            let members = &mut order[start as usize..start as usize + groups[g].len()];
            members.copy_from_slice(&groups[g]);
            let root = self.build(quads, scene.centres, members, start);
            self.roots[g] = root;
            return root;
        }
        let all: Vec<u32> = ids
            .iter()
            .flat_map(|&g| groups[g as usize].iter().copied())
            .collect();
        let bound = Bound::of_patches(quads, &all);
        let total: f64 = ids.iter().map(|&g| scene.area[g as usize]).sum();
        let weighted = ids.iter().fold([0.0; 3], |s, &g| {
            add(s, scale(scene.centre[g as usize], scene.area[g as usize]))
        });
        let me = self.nodes.len();
        self.nodes.push(Cluster {
            bound,
            members: (start, start + all.len() as u32),
            children: [0; 2],
            area: total,
            centre: scale(weighted, 1.0 / total),
            member_diameter: ids
                .iter()
                .map(|&g| scene.member_diameter[g as usize])
                .fold(0.0, f64::max),
        });
        let half = halve(
            ids,
            largest(ids.iter().map(|&g| scene.diameter[g as usize])),
            bound.diameter(),
            total,
            |g| scene.area[g as usize],
            |g| scene.centre[g as usize],
        );
        let (left, right) = ids.split_at_mut(half);
        let count = left
            .iter()
            .map(|&g| groups[g as usize].len())
            .sum::<usize>() as u32;
        let a = self.build_top(scene, left, order, start);
        let b = self.build_top(scene, right, order, start + count);
        self.nodes[me].children = [a, b];
        CLUSTER | me as u32
    }

    fn build(
        &mut self,
        quads: &[Parallelogram],
        centres: &[V3],
        members: &mut [u32],
        start: u32,
    ) -> u32 {
        if members.len() == 1 {
            return members[0];
        }
        let bound = Bound::of_patches(quads, members);
        let area: f64 = members.iter().map(|&m| quads[m as usize].area).sum();
        let centre = scale(
            members.iter().fold([0.0; 3], |s, &m| {
                add(s, scale(centres[m as usize], quads[m as usize].area))
            }),
            1.0 / area,
        );
        let (big, size) = largest(members.iter().map(|&m| quads[m as usize].diameter()));
        let me = self.nodes.len();
        self.nodes.push(Cluster {
            bound,
            members: (start, start + members.len() as u32),
            children: [0; 2],
            area,
            centre,
            member_diameter: size,
        });
        let half = if bound.cos <= 0.0 {
            // members that face opposite ways: halved by their normals first
            facing_halves(members, |m| quads[m as usize].n)
        } else {
            halve(
                members,
                (big, size),
                bound.diameter(),
                area,
                |m| quads[m as usize].area,
                |m| centres[m as usize],
            )
        };
        let (left, right) = members.split_at_mut(half);
        let a = self.build(quads, centres, left, start);
        let b = self.build(quads, centres, right, start + half as u32);
        self.nodes[me].children = [a, b];
        CLUSTER | me as u32
    }

    pub(super) fn get(&self, reference: u32) -> &Cluster {
        &self.nodes[(reference & !CLUSTER) as usize]
    }

    /// The member of cluster `reference` at the share `u` ∈ [0, 1) of its area, in the order
    /// of its members: a member picked by area from a uniform `u`.
    pub(super) fn pick(&self, reference: u32, u: f64) -> usize {
        self.pick_in(&self.prefix, reference, u)
    }

    /// The member of cluster `reference` at the share `u` ∈ [0, 1) of its light
    /// ([`Clusters::weigh_light`]): a member picked by the light it sends.
    pub(super) fn pick_by_light(&self, reference: u32, u: f64) -> usize {
        self.pick_in(&self.light, reference, u)
    }

    fn pick_in(&self, prefix: &[f64], reference: u32, u: f64) -> usize {
        let (a, b) = self.get(reference).members;
        let (a, b) = (a as usize, b as usize);
        let target = prefix[a] + u * (prefix[b] - prefix[a]);
        // the first member whose run ends beyond the target
        let k = a + prefix[a + 1..=b].partition_point(|&x| x <= target);
        self.order[k.min(b - 1)] as usize
    }

    /// Weighs each patch's weighed area ([`Clusters::weigh`]) by `radiosity(patch)`, the
    /// mean B it sends, for [`Clusters::pick_by_light`] and [`Clusters::light`].
    pub(super) fn weigh_light(&mut self, radiosity: impl Fn(usize) -> f64) {
        let mut sum = 0.0;
        self.light.clear();
        self.light.push(0.0);
        for (k, &p) in self.order.iter().enumerate() {
            sum += (self.prefix[k + 1] - self.prefix[k]) * radiosity(p as usize).max(0.0);
            self.light.push(sum);
        }
    }

    /// The light that cluster `reference`, or the patch `reference` names, sends
    /// ([`Clusters::weigh_light`]; 0 before it is weighed).
    pub(super) fn light(&self, reference: u32) -> f64 {
        if self.light.is_empty() {
            return 0.0;
        }
        let (a, b) = self.run(reference);
        self.light[b] - self.light[a]
    }

    /// The run of `order` that cluster `reference`, or the patch `reference` names, holds.
    fn run(&self, reference: u32) -> (usize, usize) {
        if is_cluster(reference) {
            let (a, b) = self.get(reference).members;
            (a as usize, b as usize)
        } else {
            let p = self.position[reference as usize] as usize;
            (p, p + 1)
        }
    }

    /// Weighs each patch's area for [`Clusters::pick`] by `share(patch)`, the share of it
    /// that takes part in the transfer: 0 for a patch wholly covered by a solid resting on
    /// it ([`crate::three_d::cover`]), which neither receives nor sends. Points drawn on it
    /// would count every ray toward it as blocked on top of its sending and receiving
    /// nothing, darkening the rest of every cluster it is in.
    pub(super) fn weigh(&mut self, quads: &[Parallelogram], share: impl Fn(usize) -> f64) {
        let mut sum = 0.0;
        self.prefix.clear();
        self.prefix.push(0.0);
        for &p in &self.order {
            sum += quads[p as usize].area * share(p as usize);
            self.prefix.push(sum);
        }
    }

    /// The area of cluster `reference`, or of the patch `reference` names, that takes part
    /// in the transfer ([`Clusters::weigh`]).
    pub(super) fn weight(&self, reference: u32) -> f64 {
        let (a, b) = self.run(reference);
        self.prefix[b] - self.prefix[a]
    }

    /// Whether some member of cluster `reference` takes part in the transfer
    /// ([`Clusters::weigh`]).
    pub(super) fn takes_part(&self, reference: u32) -> bool {
        let (a, b) = self.get(reference).members;
        self.prefix[b as usize] > self.prefix[a as usize]
    }

    /// The patches of cluster `reference`.
    pub(super) fn members(&self, reference: u32) -> &[u32] {
        let (a, b) = self.get(reference).members;
        &self.order[a as usize..b as usize]
    }

    /// Where cluster `reference`'s members lie in [`Clusters::order`].
    pub(super) fn span(&self, reference: u32) -> std::ops::Range<usize> {
        let (a, b) = self.get(reference).members;
        a as usize..b as usize
    }

    /// Where patch `patch` lies in [`Clusters::order`].
    pub(super) fn place(&self, patch: u32) -> usize {
        self.position[patch as usize] as usize
    }

    /// Every patch under a tree, each cluster's members one run of it.
    pub(super) fn order(&self) -> &[u32] {
        &self.order
    }
}

/// Whether `reference` names a cluster rather than an element.
pub(super) fn is_cluster(reference: u32) -> bool {
    reference & CLUSTER != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::three_d::geometry::Parallelogram;

    fn tri(a: V3, b: V3, c: V3) -> Parallelogram {
        let mut p = Parallelogram::new(&[a, b, add(b, sub(c, a)), c]);
        p.tri = true;
        p.area = 0.5 * p.jac;
        p
    }

    /// A tilted plane cut into triangles: no part of it faces another.
    #[test]
    fn parts_of_one_plane_never_face() {
        let (u, v) = ([1.0, 0.2, 0.3], [-0.1, 1.0, 0.4]);
        let at = |i: f64, j: f64| add(scale(u, i), scale(v, j));
        let mut quads = Vec::new();
        for i in 0..8 {
            for j in 0..8 {
                let (i, j) = (i as f64, j as f64);
                quads.push(tri(at(i, j), at(i + 1.0, j), at(i, j + 1.0)));
                quads.push(tri(at(i + 1.0, j), at(i + 1.0, j + 1.0), at(i, j + 1.0)));
            }
        }
        let tree = Clusters::new(&quads, &[(0..128).collect()]);
        assert_eq!(tree.order.len(), 128);
        for a in &tree.nodes {
            for b in &tree.nodes {
                assert!(!a.bound.facing(&b.bound));
            }
        }
    }

    /// The tree over several meshes: its root holds every triangle once, each mesh's own
    /// tree is a subtree of it, every cluster's members are its children's, and a mesh as
    /// large as half the scene (a floor under small tiles) is split off alone at the top; a
    /// surface of one patch is a start of its own, outside the tree.
    #[test]
    fn one_tree_holds_every_mesh_as_a_subtree() {
        let half = |o: V3, s: f64| {
            let (a, b, c) = (
                add(o, [s, 0.0, 0.0]),
                add(o, [s, s, 0.0]),
                add(o, [0.0, s, 0.0]),
            );
            [tri(o, a, c), tri(a, b, c)]
        };
        // a 10 × 10 floor of two triangles, eight tiles of two triangles above it and a
        // parallelogram, one group each
        let mut quads: Vec<Parallelogram> = half([0.0; 3], 10.0).to_vec();
        let mut groups = vec![vec![0u32, 1]];
        for k in 0..8 {
            let a = quads.len() as u32;
            quads.extend(half([k as f64, 1.0 + (k % 3) as f64, 1.0], 0.5));
            groups.push(vec![a, a + 1]);
        }
        let lone = quads.len() as u32;
        quads.push(Parallelogram::new(&[
            [0.0, 0.0, 5.0],
            [1.0, 0.0, 5.0],
            [1.0, 1.0, 5.0],
            [0.0, 1.0, 5.0],
        ]));
        groups.push(vec![lone]);
        let tree = Clusters::new(&quads, &groups);
        let &[single, top] = &tree.starts[..] else {
            panic!("{:?}", tree.starts)
        };
        assert_eq!(single, lone);
        assert!(is_cluster(top));
        let mut all = tree.members(top).to_vec();
        all.sort_unstable();
        assert_eq!(all, (0..lone).collect::<Vec<_>>());
        assert_eq!(
            tree.get(top).children[0],
            tree.roots[0],
            "the floor split off alone"
        );
        for (g, &root) in groups.iter().zip(&tree.roots).take(9) {
            let mut held = tree.members(root).to_vec();
            held.sort_unstable();
            assert_eq!(&held, g);
        }
        for node in &tree.nodes {
            let own: usize = node
                .children
                .iter()
                .map(|&c| {
                    if is_cluster(c) {
                        tree.members(c).len()
                    } else {
                        1
                    }
                })
                .sum();
            assert_eq!(own as u32, node.members.1 - node.members.0);
        }
    }

    /// Two squares face to face across a gap face each other, and not when one is turned away.
    #[test]
    fn facing_squares_face() {
        let floor = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]);
        let ceiling = Parallelogram::new(&[
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, 0.0, 1.0],
        ]);
        let roof = Parallelogram::new(&[
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ]);
        let b = |q: &Parallelogram| Bound::of_patches(std::slice::from_ref(q), &[0]);
        assert!(b(&floor).facing(&b(&ceiling)));
        assert!(!b(&floor).facing(&b(&roof)));
        assert!(b(&floor).front(&b(&roof)) && !b(&roof).front(&b(&floor)));
    }

    /// A square is wholly in front of another that faces it across a gap, not of one that
    /// stands on its edge (its foot is in the first's plane), nor of one beside it in its
    /// plane; a cluster of a roof's two slopes is wholly in front of a point high above it,
    /// not of one low beside it that one slope turns its back on.
    #[test]
    fn wholly_in_front() {
        let square = |o: V3, u: V3, v: V3| {
            let q = Parallelogram::new(&[o, add(o, u), add(add(o, u), v), add(o, v)]);
            Bound::of_patches(std::slice::from_ref(&q), &[0])
        };
        let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let floor = square([0.0; 3], x, y);
        let ceiling = square([0.0, 1.0, 1.0], x, scale(y, -1.0));
        let wall = square([0.0, 1.0, 0.0], x, z);
        let beside = square([1.0, 0.0, 0.0], x, y);
        assert!(floor.before(&ceiling) && ceiling.before(&floor));
        assert!(!floor.before(&wall));
        assert!(!floor.before(&beside));
        let slope =
            |o: V3, u: V3, v: V3| Parallelogram::new(&[o, add(o, u), add(add(o, u), v), add(o, v)]);
        let roof = [
            slope([0.0, 0.0, 0.0], [1.0, 0.0, 0.3], y),
            slope([-1.0, 0.0, 0.3], [1.0, 0.0, -0.3], y),
        ];
        let both = Bound::of_patches(&roof, &[0, 1]);
        let high = square([0.0, 0.0, 5.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]);
        let low = square([3.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]);
        assert!(both.before(&high));
        assert!(!both.before(&low));
    }

    /// Every patch is in the tree once, and each cluster's box, cone, slab and area hold its
    /// members.
    #[test]
    fn a_covered_patch_is_never_picked_and_a_cluster_of_them_takes_no_part() {
        let quads = strip_of_triangles();
        let mut tree = Clusters::new(&quads, &[(0..16).collect()]);
        // the patches 0..8 covered
        tree.weigh(&quads, |p| f64::from(p >= 8));
        let root = tree.starts[0];
        let mut picked = [0usize; 16];
        for i in 0..1000 {
            picked[tree.pick(root, (i as f64 + 0.5) / 1000.0)] += 1;
        }
        assert!(picked[..8].iter().all(|&n| n == 0), "{picked:?}");
        // the rest by area: equal shares
        assert!(
            picked[8..].iter().all(|&n| n.abs_diff(125) <= 1),
            "{picked:?}"
        );
        assert!(tree.takes_part(root));
        for (i, _) in tree.nodes.iter().enumerate() {
            let c = CLUSTER | i as u32;
            let any = tree.members(c).iter().any(|&m| m >= 8);
            assert_eq!(tree.takes_part(c), any);
        }
        assert!((0..tree.nodes.len()).any(|i| !tree.takes_part(CLUSTER | i as u32)));
    }

    /// Sixteen triangles of area ½ side by side in one plane, facing up.
    fn strip_of_triangles() -> Vec<Parallelogram> {
        (0..16)
            .map(|k| {
                let x = k as f64;
                tri([x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 0.0, -1.0])
            })
            .collect()
    }

    /// Picked by light, a member comes up in proportion to its weighed area times its B:
    /// never where either is 0, and a cluster's light is the sum of its members'.
    #[test]
    fn members_are_picked_by_the_light_they_send() {
        let quads = strip_of_triangles();
        let mut tree = Clusters::new(&quads, &[(0..16).collect()]);
        let root = tree.starts[0];
        assert_eq!(tree.light(root), 0.0, "no light before it is weighed");
        // 0..4 covered; B = 1 on 4..12, 3 on 12..15, 0 on 15
        tree.weigh(&quads, |p| f64::from(p >= 4));
        let b = |p: usize| match p {
            12..15 => 3.0,
            15 => 0.0,
            _ => 1.0,
        };
        tree.weigh_light(b);
        // each patch's area is ½: the light 8 · ½ + 3 · 3 · ½
        assert!(
            (tree.light(root) - 8.5).abs() < 1e-12,
            "{}",
            tree.light(root)
        );
        let mut picked = [0usize; 16];
        let n = 17_000;
        for i in 0..n {
            picked[tree.pick_by_light(root, (i as f64 + 0.5) / n as f64)] += 1;
        }
        for (p, &count) in picked.iter().enumerate() {
            let want = if p < 4 {
                0.0
            } else {
                0.5 * b(p) / 8.5 * n as f64
            };
            assert!((count as f64 - want).abs() <= 1.0, "{p}: {picked:?}");
        }
        for (i, _) in tree.nodes.iter().enumerate() {
            let c = CLUSTER | i as u32;
            let sum: f64 = tree.members(c).iter().map(|&m| tree.light(m)).sum();
            assert!((tree.light(c) - sum).abs() < 1e-12);
        }
    }

    #[test]
    fn the_tree_holds_every_patch_once_and_bounds_its_members() {
        let mut quads = Vec::new();
        for k in 0..40 {
            let x = k as f64 * 0.37;
            quads.push(tri(
                [x, 0.0, (k % 3) as f64],
                [x + 0.5, 0.1, 0.2],
                [x, 0.7, 0.1],
            ));
        }
        let tree = Clusters::new(&quads, &[(0..40).collect()]);
        let mut seen = tree.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..40).collect::<Vec<u32>>());
        for (i, c) in tree.nodes.iter().enumerate() {
            let members = tree.members(CLUSTER | i as u32);
            for &m in members {
                let q = &quads[m as usize];
                assert!(dot(q.n, c.bound.axis) >= c.bound.cos - 1e-9);
                for p in q.outline() {
                    let x = dot(c.bound.axis, p);
                    assert!(x >= c.bound.slab[0] - 1e-9 && x <= c.bound.slab[1] + 1e-9);
                    assert!((0..3).all(|a| p[a] >= c.bound.lo[a] && p[a] <= c.bound.hi[a]));
                }
            }
            let area: f64 = members.iter().map(|&m| quads[m as usize].area).sum();
            assert!((area - c.area).abs() < 1e-9 * area);
        }
    }
}

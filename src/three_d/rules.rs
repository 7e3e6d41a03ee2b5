//! The named rules of the 3D refinement beyond its one error estimate, with their constants.
//!
//! The oracle of `three_d::hierarchy` holds each link's estimate of the error it makes in its
//! receiver's basis (the transfer's variation over the receiver, weighted by what the source
//! carries; Gortler, Schröder, Cohen and Hanrahan 1993) to a tolerance shared among the
//! receiver's sources. Each rule here bounds an error that this estimate does not see, and
//! says which: the value of every constant is a field of [`Rules`], and [`Rules::DEFAULT`]
//! is what every job is solved with (`wavrad::job::run_with` takes others).
//!
//! `tests/rules.rs` solves two scenes with a rule turned off (`Rules::without_*`) against the
//! path tracer: each meets its requirement with every rule and misses it without that one
//! (coarse receivers first, lids, the shadow budget, contact lines, near occluders). The rules
//! whose need is not one scene's accuracy are held by the unit tests of the code that applies
//! them (dim receivers, partly covered senders, separated clusters). The contact lines are what puts a
//! small object's sides right (the gallery's small cube: 0 with them, 2.92 % beyond the noise
//! without); the shadow budget, a budget per receiver for the partly visible links, does not
//! replace them (the rays of a coarse receiver's links mostly miss the shadow at the foot, and
//! a link all of whose rays pass is not partly visible).
//!
//! Numerical constants that are not rules (the grid of the visible fraction, the quadrature
//! of a block, the budget of links) stay with the code they size.

/// The constants of the refinement's rules (see the module's doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rules {
    /// **Contact lines**: the share of the tolerance for a receiver along a line where another
    /// surface stands on its surface, when something may come between it and the source; the
    /// pair is judged before any ray, and split on the receiver's side whatever the two
    /// pieces' sizes. The error it bounds: next to such a line (a box's foot on a floor) the
    /// standing surface hides up to half of what the receiver sees, and rays drawn from inside
    /// a coarse receiver mostly miss that shadow. The error is the receiver's, so splitting
    /// the larger piece when that is the source leaves it where it was: in the gallery's room
    /// with a small cube, the walls' pieces each passed the share on a 1.25-unit floor element
    /// and together lit the floor's first 8 cm at the cube's foot 18 % too bright, and the
    /// cube's sides 1.9 % (0.3 % when the receiver is split). On the Cornell box's floor in
    /// front of the short block, 1 / 5 / 10 units from its foot, the whole tolerance left B
    /// +40 / +24 / +16 % bright; half of it, +14 / +3 / −0.4 %, for 65 k → 70 k links (a
    /// quarter: +4 / −4 / −5 %, 77 k). 1 turns the rule off.
    pub contact_share: f64,
    /// **Dim receivers**: the least share of the tolerance for a receiver whose own B is
    /// below the typical B (the share is their ratio, `three_d::hierarchy`'s `tolerance`).
    /// The error it bounds: none; it keeps the tolerance above 0 on a receiver whose B goes
    /// to 0 (a surface hidden from everything), whose links' estimates bound the unoccluded
    /// transfer and do not shrink with its B, so that the refinement ends. 0 would let it
    /// split such a receiver to the finest level against every source.
    pub dim_share: f64,
    /// **Coarse receivers first**: receivers coarser than a 2^level × 2^level split of their
    /// surface are split before their sources at order 0; one level fewer for each doubling
    /// of m + 1 (4 × 4 at orders 1 and 2, 2 × 2 from order 3), so that each element then spans
    /// about m + 1 cells of the result's default 8 × 8 grid. The error it bounds: splitting
    /// the larger piece (Hanrahan, Salzman and Aupperle 1991) divides a large source's
    /// transfer into parts whose estimates are each small, but leaves the receiver's one
    /// polynomial to hold the curvature of all of them; in a room with a small light in its
    /// ceiling the walls' cells came out 5 % off at their corners at order 1 (36 % at order 0)
    /// with every surface mean right to 0.1 %; with the rule 0.05 % (1.7 % at order 0), and
    /// the Cornell box's cells 0.53 → 0.25 % (3.7 → 0.76 % at order 0), for 8 % more links at
    /// order 1. Below that level the larger piece is split: to split receivers first at every
    /// level cost up to twelve times the links, for no better cells. 0 turns the rule off.
    pub receiver_first_level: u32,
    /// **Partly covered senders**: an element partly covered by a solid resting on it sends
    /// the eigenvectors of its masked Gram matrix whose eigenvalue is at least this share of
    /// the least well determined one of an element half covered ([`super::cover`]). The
    /// error it bounds: an element sends its polynomial over the whole of it and the rays
    /// take the covered part back out, which is right while the polynomial under the solid is
    /// of the size it has on the exposed part; an eigenvector that a thin exposed sliver
    /// barely determines is 1/√λ larger under the solid and the fit scales it by 1/λ. Between
    /// books 3 mm apart (λ = 1.4e-3 at order 1) the continuation under them carried so much
    /// light that below ε = 5e-4 the iteration diverged. At order 1 the cut-off is 3.6e-3 of
    /// the largest eigenvalue (a sent eigenvector is at most 17 times larger over the element
    /// than where it is seen); from order 2 on it is below the fit's own cut-off, and nothing
    /// changes. A cut-off of 1e-2 at every order dropped eigenvectors the fit keeps at orders
    /// 2 and 3 and put the Cornell box's ceiling at order 3 0.88 % off; 3e-3 made order 2 on
    /// the gallery's rotated boxes twice as far from the tracer as order 1. 0 sends every
    /// eigenvector the fit keeps.
    pub sending_share: f64,
    /// **Lids**: how close a surface must lie in front of another, facing the same way and
    /// over part of it, as a share of its own width, to be taken for a lid whose outline is
    /// masked like a solid's foot ([`super::cover`]). The error it bounds: the surface behind
    /// a ceiling light hung just below it sees only the light's back through a grazing sliver,
    /// so it is dark up to the light's outline, where one polynomial over both sides smears it
    /// (the Cornell box without blocks, its light 1 unit below the ceiling: the four cells
    /// above it 40 % bright, those around 8 % dark), and a smeared element sends light from a
    /// polynomial darkened by its dark part through a visible fraction lowered by the same
    /// part (a rug 5 mm above a meshed floor left the room 1–2 % dark). Since the shadow
    /// budget ([`Rules::shadow_share`]), the hung light's ceiling meets the gallery's
    /// requirement without lids as well; a rug does not (the floor under it comes out lit,
    /// and the room around the meshed one 1.5 % dark). 0 turns it off.
    pub lid_gap: f64,
    /// **Separated clusters**: the least distance between the boxes of a cluster link's ends,
    /// in their larger diameter. The error it bounds: taking both ends as points is a fair
    /// kernel only for separated ends (any two of their points are then within a factor 3 of
    /// the centres' distance, and the transfer stays below the form factor of a disc of the
    /// ends' size at that distance), which keeps the iteration a contraction whatever B the
    /// source has when the link is accepted: a dark source passes the oracle at any distance
    /// before the first solve.
    pub separation: f64,
    /// **Shadow budget**: the share of a leaf's tolerance that the errors of the partly
    /// visible links into it and its ancestors may add up to, on each of its step cells
    /// (`three_d::hierarchy`'s `shadows`). The error it bounds: the oracle holds each link
    /// alone to the tolerance, and bounds a partly visible one by its whole transfer, so such
    /// links are kept at any level while each carries less than the tolerance; but they smear
    /// their shadows over their receivers the same way (where a ball rests on a floor, every
    /// wall's link into the floor's element that holds the contact point sends light into the
    /// ball's shadow), and their errors add up with one sign. The gallery's meshes on a floor:
    /// the ball's bottom triangles 125 % off the tracer beyond its noise without it, at the
    /// defaults. Infinity turns it off.
    pub shadow_share: f64,
    /// **Near occluders**: how close, in the receiver's diameters, a surface that may come
    /// between a receiver and its source must lie to the receiver for the pair to lose the
    /// smoothness credit whatever its rays found. The error it bounds: an occluder that close
    /// casts a shadow on the receiver about as narrow as its distance (a shelf 10 cm in front
    /// of a wall, 4 cm thick: the wall's strip behind and above it loses the front wall and
    /// the floor behind the shelf), which the rays of a coarse pair, drawn from inside the
    /// receiver, can all miss; credited as smooth, the pair was kept at levels whose
    /// receivers span the shelf's height, and the wall there came out 2–4 % bright and the
    /// shelf's side toward it 2.06 % beyond the tracer's noise at ε = 1e-3, no better at
    /// 2.5e-4 (2.09 %) or at a finer size; with the rule 1.28 % and 0.15 %. It is the
    /// contact lines' error (an occluder at distance 0) apart from the receiver, and leaves
    /// the receivers along a contact line to that rule. A pair none of whose rays got
    /// through keeps the rays' bound. 0 turns it off.
    pub near_occluders: f64,
}

impl Default for Rules {
    fn default() -> Rules {
        Rules::DEFAULT
    }
}

impl Rules {
    /// The rules every job is solved with.
    pub const DEFAULT: Rules = Rules {
        contact_share: 0.5,
        dim_share: 0.0625,
        receiver_first_level: 3,
        sending_share: 0.05,
        lid_gap: 0.02,
        separation: 1.0,
        shadow_share: 1.0,
        near_occluders: 1.0,
    };

    /// The default rules without the contact lines (their share 1: a receiver along a contact
    /// line is judged as any other).
    pub fn without_contact_lines() -> Rules {
        Rules {
            contact_share: 1.0,
            ..Rules::default()
        }
    }

    /// The default rules without splitting coarse receivers first.
    pub fn without_receivers_first() -> Rules {
        Rules {
            receiver_first_level: 0,
            ..Rules::default()
        }
    }

    /// The default rules without lids.
    pub fn without_lids() -> Rules {
        Rules {
            lid_gap: 0.0,
            ..Rules::default()
        }
    }

    /// The default rules without the shadow budget.
    pub fn without_shadow_budget() -> Rules {
        Rules {
            shadow_share: f64::INFINITY,
            ..Rules::default()
        }
    }

    /// The default rules without the near occluders.
    pub fn without_near_occluders() -> Rules {
        Rules {
            near_occluders: 0.0,
            ..Rules::default()
        }
    }

    /// The level above which a receiver is split before its source at `order`
    /// ([`Rules::receiver_first_level`]).
    pub(crate) fn receiver_first(&self, order: usize) -> u32 {
        self.receiver_first_level
            .saturating_sub((order + 1).ilog2())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coarse_receivers_first_span_about_m_plus_1_cells_of_an_8_by_8_grid() {
        let r = Rules::default();
        // 2^level elements per side, each about (m + 1) of 8 cells wide
        let sides: Vec<u32> = (0..5).map(|m| 1 << r.receiver_first(m)).collect();
        assert_eq!(sides, [8, 4, 4, 2, 2]);
        assert_eq!(Rules::without_receivers_first().receiver_first(0), 0);
    }

    #[test]
    fn each_rule_can_be_turned_off_alone() {
        let d = Rules::default();
        for (off, changed) in [
            (Rules::without_contact_lines(), "contact"),
            (Rules::without_receivers_first(), "receivers"),
            (Rules::without_lids(), "lids"),
            (Rules::without_shadow_budget(), "shadows"),
            (Rules::without_near_occluders(), "near"),
        ] {
            let fields = [
                off.contact_share != d.contact_share,
                off.receiver_first_level != d.receiver_first_level,
                off.lid_gap != d.lid_gap,
                off.dim_share != d.dim_share,
                off.sending_share != d.sending_share,
                off.separation != d.separation,
                off.shadow_share != d.shadow_share,
                off.near_occluders != d.near_occluders,
            ];
            assert_eq!(fields.iter().filter(|&&f| f).count(), 1, "{changed}");
        }
    }
}

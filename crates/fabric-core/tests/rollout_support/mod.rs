//! Helpers shared by the `rollout_*` integration tests.
#![allow(dead_code)]

use fabric_core::rollout::SequenceResult;

/// Every number of a sequence result as bits (cost, clearance, t*, final q and q̇, and the trajectory
/// when recorded), for bit-identity checks across thread counts.
pub fn bits(r: &SequenceResult) -> Vec<u64> {
    let mut v: Vec<u64> = vec![r.cost.to_bits(), r.min_clearance.to_bits()];
    v.extend(
        r.t_stars
            .iter()
            .chain(&r.q)
            .chain(&r.qd)
            .map(|x| x.to_bits()),
    );
    if let Some(tr) = &r.trajectory {
        v.extend(
            tr.t.iter()
                .chain(&tr.q)
                .chain(&tr.qd)
                .chain(&tr.qdd)
                .map(|x| x.to_bits()),
        );
    }
    v
}

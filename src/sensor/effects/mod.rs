//! The effect catalogue: each effect = simulate (applied by the realism operator in physical
//! order) + diagnostic statistics + a fit from captures, one file each. The gap-workflow issue
//! fills it; until then the catalogue is empty and a profile naming an effect is rejected
//! rather than having the effect silently ignored.

/// Ids of the effects this build implements, in physical order.
pub fn known() -> Vec<&'static str> {
    Vec::new()
}

pub fn is_known(id: &str) -> bool {
    known().contains(&id)
}

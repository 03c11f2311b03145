//! Which weight slot to run, and which to write next.
//!
//! The head keeps two slots (A and B, see [`crate::runtime::layout`]). At boot it runs the valid slot
//! with the higher generation (A on a tie); with none valid it falls back to the traditional
//! method. "Valid" means what the head runs: the blob decodes *and* the head can run it; the
//! head's module classifies raw bytes into a [`SlotState`] (its `slot_state`), and its boot and
//! `hvs flash` both decide with the rules here. This module depends on no other of the crate's
//! logic (only the blob's error type and the slot names), so the rules stay pure. A new model is written into the slot that is *not* running,
//! with the next generation number, so a write cut off half-way leaves the running model
//! untouched. These are the pure rules shared by the firmware (boot) and `hvs flash` (plan).

use crate::runtime::blob::BlobError;
use crate::runtime::layout::Slot;

/// What a slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotState {
    /// Erased or never written: no blob magic at the start.
    Empty,
    /// A blob was there but it is damaged or unreadable.
    Invalid(BlobError),
    /// A valid blob of this generation that the head can run.
    Valid {
        /// Its generation number.
        generation: u32,
    },
    /// A blob that decodes but that the head cannot run (e.g. Z-only outputs): never booted.
    Unrunnable {
        /// Its generation number.
        generation: u32,
    },
}

impl SlotState {
    /// The generation if valid (runnable).
    pub fn generation(self) -> Option<u32> {
        match self {
            SlotState::Valid { generation } => Some(generation),
            _ => None,
        }
    }
}

/// The slot to boot: the valid one with the higher generation (A on a tie), or `None`.
pub fn choose_boot(a: SlotState, b: SlotState) -> Option<Slot> {
    match (a.generation(), b.generation()) {
        (Some(ga), Some(gb)) => Some(if gb > ga { Slot::B } else { Slot::A }),
        (Some(_), None) => Some(Slot::A),
        (None, Some(_)) => Some(Slot::B),
        (None, None) => None,
    }
}

/// Which slot the user asked to write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotRequest {
    /// The slot that is not running.
    Auto,
    /// This slot.
    Exactly(Slot),
}

/// What a write will do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WritePlan {
    /// Slot to erase and write.
    pub slot: Slot,
    /// Generation to stamp into the new blob (higher than any valid, i.e. runnable, one).
    pub generation: u32,
    /// The slot running now, which the write leaves intact (if any).
    pub running: Option<Slot>,
}

/// Why no write can be planned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanError {
    /// The requested slot holds the only model the head runs: overwriting it could leave the head
    /// without one if the write is cut off.
    WouldOverwriteOnlyModel(Slot),
    /// A generation of `u32::MAX` is already in use.
    GenerationExhausted,
}

impl core::fmt::Display for PlanError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PlanError::WouldOverwriteOnlyModel(s) => {
                write!(
                    f,
                    "slot {s:?} holds the only model the head can run; write the other slot (--slot auto)"
                )
            }
            PlanError::GenerationExhausted => f.write_str("generation numbers exhausted"),
        }
    }
}

/// Plans a write given what both slots hold.
pub fn plan_write(a: SlotState, b: SlotState, req: SlotRequest) -> Result<WritePlan, PlanError> {
    let running = choose_boot(a, b);
    let max_gen = match (a.generation(), b.generation()) {
        (Some(x), Some(y)) => Some(x.max(y)),
        (x, y) => x.or(y),
    };
    let generation = match max_gen {
        Some(g) => g.checked_add(1).ok_or(PlanError::GenerationExhausted)?,
        None => 1,
    };
    let slot = match req {
        SlotRequest::Auto => running.map_or(Slot::A, Slot::other),
        SlotRequest::Exactly(s) => {
            let other_valid = match s {
                Slot::A => b.generation().is_some(),
                Slot::B => a.generation().is_some(),
            };
            if running == Some(s) && !other_valid {
                return Err(PlanError::WouldOverwriteOnlyModel(s));
            }
            s
        }
    };
    Ok(WritePlan { slot, generation, running })
}

#[cfg(test)]
mod tests {
    use super::*;

    const E: SlotState = SlotState::Empty;
    const I: SlotState = SlotState::Invalid(BlobError::BadCrc);
    /// A Z-only (unrunnable) blob of a high generation.
    const U: SlotState = SlotState::Unrunnable { generation: 9 };
    const fn v(g: u32) -> SlotState {
        SlotState::Valid { generation: g }
    }

    #[test]
    fn boot_choice_for_every_combination() {
        let states = [E, I, U, v(1), v(2)];
        for a in states {
            for b in states {
                let got = choose_boot(a, b);
                let want = match (a.generation(), b.generation()) {
                    (None, None) => None,
                    (Some(_), None) => Some(Slot::A),
                    (None, Some(_)) => Some(Slot::B),
                    (Some(x), Some(y)) => Some(if y > x { Slot::B } else { Slot::A }),
                };
                assert_eq!(got, want, "{a:?} {b:?}");
                // Never an invalid or empty slot.
                if let Some(s) = got {
                    let st = if s == Slot::A { a } else { b };
                    assert!(st.generation().is_some());
                }
            }
        }
    }

    #[test]
    fn auto_writes_the_slot_not_running_with_the_next_generation() {
        let states = [E, I, U, v(1), v(5)];
        for a in states {
            for b in states {
                let p = plan_write(a, b, SlotRequest::Auto).unwrap();
                let running = choose_boot(a, b);
                assert_eq!(p.running, running);
                assert_ne!(Some(p.slot), running, "{a:?} {b:?}");
                let max = a.generation().into_iter().chain(b.generation()).max();
                assert_eq!(p.generation, max.map_or(1, |g| g + 1));
                // After the write succeeds, the new model is the one that boots.
                let (na, nb) =
                    if p.slot == Slot::A { (v(p.generation), b) } else { (a, v(p.generation)) };
                assert_eq!(choose_boot(na, nb), Some(p.slot));
                // If it is cut off, the old model (if any) still boots.
                let (ca, cb) = if p.slot == Slot::A { (I, b) } else { (a, I) };
                assert_eq!(choose_boot(ca, cb), running);
            }
        }
        assert_eq!(plan_write(E, E, SlotRequest::Auto).unwrap().slot, Slot::A);
    }

    #[test]
    fn an_unrunnable_blob_of_a_higher_generation_is_not_the_running_slot() {
        // A: Z-only at generation 9, B: runnable at 7. The head runs B, so auto writes A,
        // with generation 8 (above the running one), and an explicit B is refused.
        let b = v(7);
        assert_eq!(choose_boot(U, b), Some(Slot::B));
        let p = plan_write(U, b, SlotRequest::Auto).unwrap();
        assert_eq!((p.slot, p.generation, p.running), (Slot::A, 8, Some(Slot::B)));
        assert_eq!(
            plan_write(U, b, SlotRequest::Exactly(Slot::B)),
            Err(PlanError::WouldOverwriteOnlyModel(Slot::B))
        );
        assert_eq!(plan_write(U, b, SlotRequest::Exactly(Slot::A)).unwrap().slot, Slot::A);
        // Nothing runnable: A, generation 1.
        let p = plan_write(U, U, SlotRequest::Auto).unwrap();
        assert_eq!((p.slot, p.generation, p.running), (Slot::A, 1, None));
    }

    #[test]
    fn explicit_slot_never_destroys_the_only_model() {
        assert_eq!(
            plan_write(v(3), E, SlotRequest::Exactly(Slot::A)),
            Err(PlanError::WouldOverwriteOnlyModel(Slot::A))
        );
        assert_eq!(
            plan_write(I, v(3), SlotRequest::Exactly(Slot::B)),
            Err(PlanError::WouldOverwriteOnlyModel(Slot::B))
        );
        let p = plan_write(v(3), v(2), SlotRequest::Exactly(Slot::A)).unwrap();
        assert_eq!((p.slot, p.generation), (Slot::A, 4));
        let p = plan_write(v(3), E, SlotRequest::Exactly(Slot::B)).unwrap();
        assert_eq!((p.slot, p.generation), (Slot::B, 4));
        assert_eq!(
            plan_write(v(u32::MAX), E, SlotRequest::Auto),
            Err(PlanError::GenerationExhausted)
        );
    }
}

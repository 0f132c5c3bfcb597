//! The simulator's still-world cache: what it computes from the chair's
//! true pose and the room alone (the camera's rendering, the lasers'
//! ranges) is given again, to the bit, while neither changed (the chair
//! held or waiting for a word: about a fifth of a benchmark's frames).

use super::room::Room;
use super::world::SimWorld;

/// The last of what the simulator computes from the chair's true pose and
/// the room alone (a rendering, laser ranges), with the pose (its bits)
/// and the room it was computed from: while the chair stands still in a
/// still room it is the answer again, to the bit.
pub(super) struct Still<T> {
    last: Option<([u64; 3], Room, T)>,
}

impl<T> Default for Still<T> {
    fn default() -> Self {
        Still { last: None }
    }
}

impl<T: Clone> Still<T> {
    /// The last answer if `w`'s chair and room are as they were for it;
    /// otherwise `compute(w)`, kept for next time.
    pub(super) fn get_or(&mut self, w: &SimWorld, compute: impl FnOnce(&SimWorld) -> T) -> T {
        match self.try_get_or(w, |w| Ok::<T, std::convert::Infallible>(compute(w))) {
            Ok(value) => value,
            Err(never) => match never {},
        }
    }

    /// As [`Still::get_or`], for a computation that may fail (kept only
    /// when it did not).
    pub(super) fn try_get_or<E>(
        &mut self,
        w: &SimWorld,
        compute: impl FnOnce(&SimWorld) -> Result<T, E>,
    ) -> Result<T, E> {
        let pose_bits = [w.truth.x_m, w.truth.y_m, w.truth.theta_rad].map(f64::to_bits);
        if let Some((bits, room, value)) = &self.last {
            if *bits == pose_bits && *room == w.room {
                return Ok(value.clone());
            }
        }
        let value = compute(w)?;
        self.last = Some((pose_bits, w.room.clone(), value.clone()));
        Ok(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The last answer is given again only for the same chair pose, to the
    /// bit, in the same room; any change computes it anew.
    #[test]
    fn a_still_world_gives_its_last_answer_and_a_changed_one_a_new_one() {
        let mut w =
            SimWorld::living_room(crate::estimation::odometry::DiffDriveParams::paper_chair());
        let mut still: Still<u32> = Still::default();
        let mut computed = 0;
        let mut ask = |w: &SimWorld, still: &mut Still<u32>| {
            still.get_or(w, |_| {
                computed += 1;
                computed
            })
        };
        assert_eq!(ask(&w, &mut still), 1);
        assert_eq!(ask(&w, &mut still), 1, "the same world: the last answer");
        w.truth.x_m = f64::from_bits(w.truth.x_m.to_bits() + 1);
        assert_eq!(
            ask(&w, &mut still),
            2,
            "moved by one unit in the last place"
        );
        w.truth.theta_rad = -0.0 * w.truth.theta_rad.signum();
        let turned = ask(&w, &mut still);
        w.truth.theta_rad = -w.truth.theta_rad;
        assert_ne!(ask(&w, &mut still), turned, "0 and -0 are different bits");
        let before = ask(&w, &mut still);
        w.room.objects[0].min_m[0] += 0.01;
        assert_eq!(ask(&w, &mut still), before + 1, "an object moved");
        assert_eq!(ask(&w, &mut still), before + 1);
        // a computation that failed is not kept
        let failed: Result<u32, &str> = still.try_get_or(&w, |_| Err("no"));
        assert!(failed.is_ok(), "the room and pose are as before: kept");
        w.truth.y_m += 0.5;
        assert_eq!(still.try_get_or(&w, |_| Err("no")), Err::<u32, _>("no"));
        assert_eq!(still.get_or(&w, |_| 99), 99);
    }
}

//! The goal keeper's step ([`GoalKeeper::update`]), state by state: what
//! one update with the tracks, the chair's pose and the obstacles makes of
//! each goal state.

use super::*;

/// What one update sees: its inputs, and the keeper's own as they were
/// when it began (the places refused, whether it is looking for another
/// side, where the goal was last seen).
struct Step<'a> {
    now: Stamp,
    tracker: &'a Tracker,
    from: [f64; 2],
    settings: GoalSettings,
    obstacles_odom: &'a [[f64; 2]],
    visible: &'a dyn Fn(&Track) -> bool,
    fits: &'a dyn Fn([f64; 2]) -> bool,
    refused: Vec<[f64; 2]>,
    refusing: bool,
    last_center: Option<[f64; 3]>,
    given_up: Vec<[f64; 2]>,
}

impl Step<'_> {
    /// Never a place the chair was held on its way to.
    fn not_refused(&self, p: [f64; 2]) -> bool {
        self.refused
            .iter()
            .all(|r| (p[0] - r[0]).hypot(p[1] - r[1]) > REFUSED_WITHIN_M)
    }

    /// The place beside `t` where it fits on the map; where no side fits
    /// there, a side as without it (what the chair sees now decides) —
    /// but never another side of the object than `side_of`'s where one is
    /// given (a side on floor never seen may lie behind the wall the
    /// object stands against, and the first side found flips as the chair
    /// moves), and none while looking for another side (it must fit).
    fn place_beside(&self, t: &Track, side_of: Option<[f64; 2]>) -> Option<ApproachPose> {
        let s = &self.settings;
        let (from, standoff_m, body_m) =
            (self.from, s.standoff_m + s.front_offset_m, s.front_offset_m);
        let (obstacles, clearance_m) = (self.obstacles_odom, s.clearance_m);
        approach_pose(t, from, standoff_m, body_m, obstacles, clearance_m, &|p| {
            (self.fits)(p) && self.not_refused(p)
        })
        .or_else(|| {
            if self.refusing {
                return None;
            }
            let bearing = |p: [f64; 2]| (p[1] - t.center_m[1]).atan2(p[0] - t.center_m[0]);
            let same_side = |p: [f64; 2]| {
                side_of.is_none_or(|q| wrap_angle(bearing(p) - bearing(q)).abs() <= SAME_SIDE_RAD)
            };
            approach_pose(t, from, standoff_m, body_m, obstacles, clearance_m, &|p| {
                self.not_refused(p) && same_side(p)
            })
        })
    }

    /// The goal's track `id` — or, where the tracker split or renumbered
    /// it, the confirmed track of `label` nearest where the goal was last
    /// seen — while it counts as in view (seen lately, or where the camera
    /// cannot see it).
    fn in_view(&self, id: u64, label: &str) -> Option<&Track> {
        let tracks = self.tracker.tracks();
        tracks
            .iter()
            .find(|t| t.id == id)
            .or_else(|| {
                let c = self.last_center?;
                tracks
                    .iter()
                    .filter(|t| t.confirmed && t.label.eq_ignore_ascii_case(label))
                    .map(|t| {
                        let d = (t.center_m[0] - c[0]).hypot(t.center_m[1] - c[1]);
                        (d, t)
                    })
                    .filter(|(d, _)| *d <= REACQUIRE_M)
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|(_, t)| t)
            })
            .filter(|t| {
                t.last_seen.age_at(self.now) <= self.settings.unseen_after || !(self.visible)(t)
            })
    }

    /// The nearest confirmed track of `label` but the objects given up.
    fn goal(&self, label: &str) -> Option<&Track> {
        self.tracker.goal_where(label, self.from, |t| {
            !given_up_at(&self.given_up, t.center_m)
        })
    }

    /// The nearest track of `label` seen lately (but the objects given up).
    fn fresh_goal(&self, label: &str) -> Option<&Track> {
        self.goal(label)
            .filter(|t| t.last_seen.age_at(self.now) <= self.settings.unseen_after)
    }
}

impl GoalKeeper {
    /// One update at `now` with the tracks, the chair's pose (odom), the
    /// obstacle points (odom) and whether a track should be seen now: a
    /// goal outside the view (too close for the camera, behind the chair
    /// while it turns) or hidden behind something is not "lost" for being
    /// unseen; the tracker drops tracks missed where they should be seen.
    /// The place beside the object is chosen where `fits` admits it (odom:
    /// where the chair fits on the map of what it has seen) when some side
    /// is; where no side is, as without it (what the chair sees now
    /// decides).
    pub fn update(
        &mut self,
        now: Stamp,
        tracker: &Tracker,
        chair: Pose2,
        obstacles_odom: &[[f64; 2]],
        visible: &dyn Fn(&Track) -> bool,
        fits: &dyn Fn([f64; 2]) -> bool,
    ) -> Option<GoalEvent> {
        let word_s = self.word_since.get_or_insert(now).age_at(now);
        if !self.given_up.is_empty() && word_s > self.settings.search_at_most {
            // an object was given up: the next is bounded by the word's
            // search time (the first one's trip is not)
            if let Some(label) = self.state.label().map(str::to_owned) {
                self.state = GoalState::None;
                return Some(GoalEvent::AnotherOutOfTime {
                    label,
                    after_s: word_s.as_secs_f64(),
                });
            }
        }
        let step = Step {
            now,
            tracker,
            from: [chair.x_m, chair.y_m],
            settings: self.settings,
            obstacles_odom,
            visible,
            fits,
            refused: self.refused.clone(),
            refusing: self.refusing,
            last_center: self.last_center,
            given_up: self.given_up.clone(),
        };
        match self.state.clone() {
            GoalState::None | GoalState::Reached { .. } => None,
            GoalState::LookingAround => self.looking_around(&step, chair),
            GoalState::Searching { label } | GoalState::Exploring { label, .. }
                if self.search_since.get_or_insert(now).age_at(now)
                    > step.settings.search_at_most
                    && step
                        .goal(&label)
                        .is_none_or(|t| t.last_seen.age_at(now) > step.settings.unseen_after) =>
            {
                self.state = GoalState::None;
                Some(word_not_found(&step.given_up, label))
            }
            GoalState::Searching { label } => self.searching(&step, chair, label),
            GoalState::Exploring { label, target, .. } if step.fresh_goal(&label).is_some() => {
                // seen on the way: as when a search turn finds it
                tracing::info!(?target, from = ?step.from, "exploring: the word seen on the way");
                self.state = GoalState::Searching { label };
                self.new_turn();
                self.update(now, tracker, chair, obstacles_odom, visible, fits)
            }
            GoalState::Exploring {
                label,
                target,
                since,
            } => {
                self.exploring(&step, label, target, since);
                None
            }
            GoalState::Tracking {
                label,
                track,
                approach,
            } => self.tracking(&step, chair, label, track, approach),
            GoalState::Holding {
                label,
                track,
                since,
            } => self.holding(&step, label, track, since),
        }
    }

    /// Looking around: once a full turn is done, what it saw, nearest
    /// first.
    fn looking_around(&mut self, step: &Step, chair: Pose2) -> Option<GoalEvent> {
        if let Some(prev) = self.search_heading {
            self.search_turned_rad += wrap_angle(chair.theta_rad - prev).abs();
        }
        self.search_heading = Some(chair.theta_rad);
        if self.search_turned_rad < std::f64::consts::TAU {
            return None;
        }
        self.state = GoalState::None;
        let from = step.from;
        let mut seen: Vec<(f64, &str)> = step
            .tracker
            .tracks()
            .iter()
            .filter(|t| t.confirmed)
            .map(|t| {
                let d = (t.center_m[0] - from[0]).hypot(t.center_m[1] - from[1]);
                (d, t.label.as_str())
            })
            .collect();
        seen.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut labels: Vec<String> = Vec::new();
        for (_, l) in seen {
            if !labels.iter().any(|x| x == l) {
                labels.push(l.to_string());
            }
        }
        Some(GoalEvent::LookedAround { seen: labels })
    }

    /// Searching (the turn on the spot): the word seen lately is the goal
    /// where there is a place beside it; unseen after the turn, "not
    /// found" unless the search goes further.
    fn searching(&mut self, step: &Step, chair: Pose2, label: String) -> Option<GoalEvent> {
        if let Some(prev) = self.search_heading {
            self.search_turned_rad += wrap_angle(chair.theta_rad - prev).abs();
        }
        self.search_heading = Some(chair.theta_rad);
        let Some(t) = step.fresh_goal(&label) else {
            if self.turned_enough() && !self.explores {
                self.state = GoalState::None;
                return Some(word_not_found(&step.given_up, label));
            }
            if self.searched.is_empty() {
                self.searched.push(step.from);
            }
            return None;
        };
        let id = t.id;
        self.last_center = Some(t.center_m);
        self.last_box = Some(SeenBox::of(t));
        self.last_confidence = t.confidence;
        match step.place_beside(t, None) {
            Some(approach) => {
                tracing::info!(
                    track = id,
                    center_m = ?t.center_m,
                    size_m = ?t.size_m,
                    hits = t.hits,
                    ?approach,
                    "goal: acquired"
                );
                self.state = GoalState::Tracking {
                    label: label.clone(),
                    track: id,
                    approach,
                };
                Some(GoalEvent::Acquired { label, track: id })
            }
            // said once per track, not at every step
            None if self.said_no_approach == Some(id) => None,
            None => {
                self.said_no_approach = Some(id);
                Some(GoalEvent::NoApproach { label, track: id })
            }
        }
    }

    /// Driving to a place to search from (the word not seen on the way):
    /// there, or driving too long, the search turns again from here.
    fn exploring(&mut self, step: &Step, label: String, target: [f64; 2], since: Stamp) {
        let from = step.from;
        let there = (target[0] - from[0]).hypot(target[1] - from[1]) <= EXPLORED_WITHIN_M;
        if there || since.age_at(step.now) > EXPLORE_FOR {
            // look again from here
            tracing::info!(
                ?target,
                ?from,
                reached = there,
                "exploring: looking again from here"
            );
            self.searched.push(from);
            self.state = GoalState::Searching { label };
            self.new_turn();
        }
    }

    /// Driving to the goal's object: a nearer one of the word becomes the
    /// goal; the place beside it re-planned as the track updates; reached
    /// there with the object seen; out of view, held.
    fn tracking(
        &mut self,
        step: &Step,
        chair: Pose2,
        label: String,
        track: u64,
        approach: ApproachPose,
    ) -> Option<GoalEvent> {
        let (s, now, from) = (&step.settings, step.now, step.from);
        let Some(t) = step.in_view(track, &label) else {
            self.state = GoalState::Holding {
                label: label.clone(),
                track,
                since: now,
            };
            return Some(GoalEvent::OutOfView { label });
        };
        self.last_confidence = t.confidence;
        if let Some((nearer, a)) = (!self.refusing)
            .then(|| step.goal(&label))
            .flatten()
            .filter(|n| {
                let d = |c: [f64; 3]| (c[0] - from[0]).hypot(c[1] - from[1]);
                n.id != t.id
                    && !stands_before(n, t, from)
                    && n.last_seen.age_at(now) <= s.unseen_after
                    && d(n.center_m) + NEARER_BY_M < d(t.center_m)
            })
            .and_then(|n| {
                let a = step.place_beside(n, None)?;
                let d = |a: &ApproachPose| (a.x_m - from[0]).hypot(a.y_m - from[1]);
                (d(&a) + NEARER_BY_M < d(&approach)).then_some((n, a))
            })
        {
            tracing::info!(
                from_track = t.id,
                to_track = nearer.id,
                hits = nearer.hits,
                misses = nearer.misses,
                streak = nearer.streak,
                confidence = nearer.confidence,
                goal_hits = t.hits,
                goal_confidence = t.confidence,
                center_m = ?nearer.center_m,
                "goal: a nearer one"
            );
            self.last_center = Some(nearer.center_m);
            self.last_box = Some(SeenBox::of(nearer));
            self.last_confidence = nearer.confidence;
            self.state = GoalState::Tracking {
                label: label.clone(),
                track: nearer.id,
                approach: a,
            };
            return Some(GoalEvent::Nearer { label });
        }
        let track = t.id;
        self.last_center = Some(t.center_m);
        self.last_box = Some(SeenBox::of(t));
        // re-planned as the track updates; where no side fits on the map,
        // on the side it is
        let beside = step.place_beside(t, Some([approach.x_m, approach.y_m]));
        let refusing = std::mem::take(&mut self.refusing);
        let a = match beside {
            Some(a) => a,
            None if refusing => {
                // no other side: the place held on the way to stays the
                // goal's
                self.refused.pop();
                approach
            }
            None => approach,
        };
        let other_side = refusing && beside.is_some();
        // arrived where the object is seen now (not a false detection's
        // track, seen a while ago and no more) (or out of the camera's
        // sight there, a track that was not missed much where it could be
        // seen: a false detection's track, missed in most views, is not
        // arrived at out of sight)
        let seen_now = t.last_seen.age_at(now) <= SEEN_ON_ARRIVAL
            || (!(step.visible)(t) && t.confidence >= TRUSTED_OUT_OF_SIGHT);
        if (a.x_m - chair.x_m).hypot(a.y_m - chair.y_m) <= s.reached_within_m && seen_now {
            tracing::info!(
                track,
                center_m = ?t.center_m,
                size_m = ?t.size_m,
                footprint = ?t.footprint,
                place = ?a,
                "goal: reached"
            );
            self.state = GoalState::Reached {
                label: label.clone(),
                track,
            };
            return Some(GoalEvent::Reached { label });
        }
        let event = other_side.then(|| GoalEvent::OtherSide {
            label: label.clone(),
        });
        self.state = GoalState::Tracking {
            label,
            track,
            approach: a,
        };
        event
    }

    /// Held out of view: back in view, tracked again; held too long, a
    /// search of its own from here (a few times a word), then lost.
    fn holding(
        &mut self,
        step: &Step,
        label: String,
        track: u64,
        since: Stamp,
    ) -> Option<GoalEvent> {
        let (s, now) = (&step.settings, step.now);
        if let Some(t) = step.in_view(track, &label) {
            let track = t.id;
            self.last_center = Some(t.center_m);
            self.last_box = Some(SeenBox::of(t));
            if let Some(approach) = step.place_beside(t, None) {
                self.state = GoalState::Tracking {
                    label: label.clone(),
                    track,
                    approach,
                };
                return Some(GoalEvent::BackInView { label });
            }
        }
        let held = since.age_at(now);
        if held > s.hold_for && self.explores && self.searched_again < SEARCH_AGAIN_AT_MOST {
            // a search of its own from here: turn, then further
            self.searched_again += 1;
            self.searched.clear();
            self.new_turn();
            self.search_since = Some(now);
            self.said_no_approach = None;
            self.state = GoalState::Searching {
                label: label.clone(),
            };
            return Some(GoalEvent::SearchingAgain {
                label,
                held_s: held.as_secs_f64(),
            });
        }
        if held > s.hold_for {
            self.state = GoalState::None;
            return Some(GoalEvent::Lost {
                label,
                held_s: held.as_secs_f64(),
            });
        }
        None
    }
}

/// Whether `near`, seen from `from` (odom), stands before `far` in the
/// same line of sight: its ground outline's bearing span overlaps
/// `far`'s. A box of the word around an object partly hidden behind
/// another holds both, and the depth segmenter takes the nearer surface
/// for the object now and then, frame after frame as the chair drives on
/// (scenes 227 and 293 of `opennav sim --seed 1`: a cabinet before a
/// sink, a table and chairs before a television, confirmed as "a nearer
/// one" and arrived at). While the goal's object is seen, such a track is
/// not taken for another of the word.
fn stands_before(near: &Track, far: &Track, from: [f64; 2]) -> bool {
    let span = |t: &Track| {
        let (dx, dy) = (t.center_m[0] - from[0], t.center_m[1] - from[1]);
        let d = dx.hypot(dy);
        let half_m = 0.5 * t.size_m[0].hypot(t.size_m[1]);
        let half_rad = if d <= half_m {
            std::f64::consts::PI
        } else {
            (half_m / d).asin()
        };
        (dy.atan2(dx), half_rad, d)
    };
    let (b_near, w_near, d_near) = span(near);
    let (b_far, w_far, d_far) = span(far);
    d_near < d_far && crate::msg::wrap_angle(b_near - b_far).abs() < w_near + w_far
}

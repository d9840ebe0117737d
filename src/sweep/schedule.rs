//! Which budgets each integrator renders: explicit or doubling, stopped by a time limit.

/// Which budgets to render for one integrator: an explicit list, or 1, 2, 4, …
/// (up to `max_budget`); either way, with a time limit, a budget is skipped (and
/// the schedule ends) when the previous render predicts that it would take the
/// integrator's total over the limit. The prediction keeps the previous render's
/// fixed cost (total − render time) and scales its render time by the budget ratio.
#[derive(Clone, Debug)]
pub struct Schedule {
    explicit: Option<Vec<u32>>,
    index: usize,
    time_limit: Option<f64>,
    max_budget: u32,
    spent: f64,
    /// (budget, render seconds, total seconds) of the previous render.
    last: Option<(u32, f64, f64)>,
}

impl Schedule {
    pub fn doubling(time_limit: Option<f64>, max_budget: u32) -> Schedule {
        Schedule { explicit: None, index: 0, time_limit, max_budget: max_budget.max(1), spent: 0.0, last: None }
    }

    pub fn explicit(budgets: Vec<u32>, time_limit: Option<f64>) -> Schedule {
        Schedule { explicit: Some(budgets), index: 0, time_limit, max_budget: u32::MAX, spent: 0.0, last: None }
    }

    /// Predicted total seconds of a render at `budget` after one at `last_budget`
    /// that took `last_render_s` rendering and `last_total_s` in all.
    pub fn predict(last_budget: u32, last_render_s: f64, last_total_s: f64, budget: u32) -> f64 {
        let fixed = (last_total_s - last_render_s).max(0.0);
        fixed + last_render_s.max(0.0) * budget as f64 / last_budget.max(1) as f64
    }

    /// The next budget to render, or `None` when the schedule is over.
    pub fn next(&self) -> Option<u32> {
        let candidate = match &self.explicit {
            Some(list) => *list.get(self.index)?,
            None => match self.last {
                None => 1,
                Some((b, _, _)) => b.checked_mul(2)?,
            },
        };
        if candidate > self.max_budget {
            return None;
        }
        if let (Some(limit), Some((b, render, total))) = (self.time_limit, self.last) {
            if self.spent + Schedule::predict(b, render, total, candidate) > limit {
                return None;
            }
        }
        Some(candidate)
    }

    /// Passes over the next budget of an explicit list without rendering it.
    pub fn skip(&mut self) {
        self.index += 1;
    }

    /// Records a finished render (`budget`: what it rendered, which may exceed what was asked).
    pub fn record(&mut self, budget: u32, render_s: f64, total_s: f64) {
        self.index += 1;
        self.spent += total_s;
        self.last = Some((budget, render_s, total_s));
    }

    pub fn spent(&self) -> f64 {
        self.spent
    }
}

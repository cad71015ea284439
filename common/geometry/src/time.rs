//! Which keyframes bracket a time (dynamic assets): the CPU reference, the GPU viewer and
//! the stream planner all blend the same two frames with the same weight.

/// Keyframes k0, k1 around a time and the weight of k1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeSlot {
    pub k0: usize,
    pub k1: usize,
    pub w: f32,
}

/// Keyframes sorted by `time_of` ascending (none: a static asset, frame 0). Clamped at
/// both ends; NaN gives the first frame.
pub fn time_slot<T>(frames: &[T], time_of: impl Fn(&T) -> f32, t: f32) -> TimeSlot {
    let first = TimeSlot { k0: 0, k1: 0, w: 0.0 };
    let Some(f0) = frames.first() else { return first };
    if !(t > time_of(f0)) {
        return first;
    }
    let last = frames.len() - 1;
    if t >= time_of(&frames[last]) {
        return TimeSlot { k0: last, k1: last, w: 0.0 };
    }
    // first frame with time > t; t > first so k >= 1, and t < last so k <= last
    let k = frames.partition_point(|f| time_of(f) <= t);
    let (a, b) = (time_of(&frames[k - 1]), time_of(&frames[k]));
    let w = if b > a { ((t - a) / (b - a)).clamp(0.0, 1.0) } else { 0.0 };
    TimeSlot { k0: k - 1, k1: k, w }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots() {
        let ts = [0.0, 1.0, 3.0];
        assert_eq!(time_slot(&[] as &[f32], |x| *x, 0.5), TimeSlot { k0: 0, k1: 0, w: 0.0 });
        assert_eq!(time_slot(&ts, |x| *x, -1.0), TimeSlot { k0: 0, k1: 0, w: 0.0 });
        assert_eq!(time_slot(&ts, |x| *x, f32::NAN), TimeSlot { k0: 0, k1: 0, w: 0.0 });
        assert_eq!(time_slot(&ts, |x| *x, 2.0), TimeSlot { k0: 1, k1: 2, w: 0.5 });
        assert_eq!(time_slot(&ts, |x| *x, 1.0), TimeSlot { k0: 1, k1: 2, w: 0.0 });
        assert_eq!(time_slot(&ts, |x| *x, 9.0), TimeSlot { k0: 2, k1: 2, w: 0.0 });
    }
}

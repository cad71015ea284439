//! Motion entries: a cell of a dynamic asset may, at a keyframe, show the reference keyframe
//! (`Header::motion_ref`) moved by an offset instead of a block of its own. Between two
//! keyframes whose entries both move, the offset is interpolated and the reference is read
//! once, so a moving limb is drawn at its place in between rather than twice, half-faded
//! (block blending). Entries with bit 31 set and bit 30 clear are motion; the low 30 bits
//! hold three signed 10-bit offsets (x, y, z) in quarter voxels, ±127.75 voxels. Block
//! indices stay below 2^31 and `EMPTY` is all ones, so the three never collide.

/// Bit pattern of a motion entry (`is_motion`).
pub const MOTION_TAG: u32 = 0x8000_0000;
/// Offset units per voxel.
pub const MOTION_SCALE: f32 = 4.0;
/// Largest offset in voxels on each axis.
pub const MOTION_MAX: f32 = 511.0 / MOTION_SCALE;

/// Is this grid entry a motion entry?
#[inline]
pub fn is_motion(e: u32) -> bool {
    e & 0xC000_0000 == MOTION_TAG
}

/// The motion entry closest to offset `d` (voxels), clamped to ±`MOTION_MAX`.
pub fn motion_entry(d: [f32; 3]) -> u32 {
    let mut e = MOTION_TAG;
    for (a, &x) in d.iter().enumerate() {
        let q = (x * MOTION_SCALE).round().clamp(-511.0, 511.0) as i32;
        e |= ((q as u32) & 0x3FF) << (10 * a);
    }
    e
}

/// The offset (voxels) of a motion entry; None for anything else.
#[inline]
pub fn motion_offset(e: u32) -> Option<[f32; 3]> {
    if !is_motion(e) {
        return None;
    }
    Some(std::array::from_fn(|a| {
        let q = ((e >> (10 * a)) & 0x3FF) as i32;
        let q = if q >= 512 { q - 1024 } else { q };
        q as f32 / MOTION_SCALE
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motion_entries_round_trip_in_quarter_voxels_and_never_look_like_blocks_or_empty() {
        for d in [[0.0, 0.0, 0.0], [1.25, -3.5, 127.75], [-127.75, 0.25, -0.75], [300.0, -300.0, 0.1]] {
            let e = motion_entry(d);
            assert!(is_motion(e));
            assert_ne!(e, crate::asset::EMPTY);
            assert!(e >= 1 << 31, "block indices are below 2^31");
            let back = motion_offset(e).unwrap();
            for a in 0..3 {
                let want = (d[a] * 4.0).round().clamp(-511.0, 511.0) / 4.0;
                assert_eq!(back[a], want, "{d:?}");
            }
        }
        assert!(!is_motion(crate::asset::EMPTY));
        assert!(!is_motion(12345));
        assert_eq!(motion_offset(7), None);
    }
}

//! Strided single-precision GEMM (`C <- alpha A B + beta C`) split across rayon threads by
//! columns of C. Strided operands let the convolutions multiply shifted views of a padded
//! image directly, without building im2col copies.

use rayon::prelude::*;

/// A strided matrix view: base pointer, row stride, column stride (in elements).
#[derive(Clone, Copy)]
pub struct View {
    pub ptr: *const f32,
    pub rs: isize,
    pub cs: isize,
}

/// A mutable strided matrix view.
#[derive(Clone, Copy)]
pub struct ViewMut {
    pub ptr: *mut f32,
    pub rs: isize,
    pub cs: isize,
}

// SAFETY: the views are only dereferenced inside `gemm`, whose callers guarantee the memory
// outlives the call and that the column ranges given to different threads write disjoint
// elements of C.
unsafe impl Send for View {}
unsafe impl Sync for View {}
unsafe impl Send for ViewMut {}
unsafe impl Sync for ViewMut {}

/// Columns per thread below which splitting costs more than it saves.
const MIN_COLUMNS_PER_TASK: usize = 256;

/// `C (m x n) <- alpha * A (m x k) * B (k x n) + beta * C`.
///
/// # Safety
/// Every element addressed by the views for the given sizes must be valid; the elements of
/// C addressed by different columns must not overlap (no aliasing between columns), and C
/// must not alias A or B.
pub unsafe fn gemm(m: usize, k: usize, n: usize, alpha: f32, a: View, b: View, beta: f32, c: ViewMut) {
    if m == 0 || n == 0 {
        return;
    }
    let threads = rayon::current_num_threads().max(1);
    let tasks = (n / MIN_COLUMNS_PER_TASK).clamp(1, threads);
    if tasks == 1 {
        matrixmultiply::sgemm(m, k, n, alpha, a.ptr, a.rs, a.cs, b.ptr, b.rs, b.cs, beta, c.ptr, c.rs, c.cs);
        return;
    }
    let chunk = n.div_ceil(tasks);
    (0..tasks).into_par_iter().for_each(|t| {
        let j0 = t * chunk;
        let j1 = ((t + 1) * chunk).min(n);
        if j0 >= j1 {
            return;
        }
        let (a, b, c) = (a, b, c);
        // SAFETY: per the function contract; column ranges [j0, j1) are disjoint per task.
        unsafe {
            matrixmultiply::sgemm(
                m,
                k,
                j1 - j0,
                alpha,
                a.ptr,
                a.rs,
                a.cs,
                b.ptr.offset(j0 as isize * b.cs),
                b.rs,
                b.cs,
                beta,
                c.ptr.offset(j0 as isize * c.cs),
                c.rs,
                c.cs,
            );
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_naive() {
        let (m, k, n) = (5, 7, 700);
        let a: Vec<f32> = (0..m * k).map(|i| (i % 13) as f32 * 0.1 - 0.5).collect();
        let b: Vec<f32> = (0..k * n).map(|i| (i % 7) as f32 * 0.2 - 0.3).collect();
        let mut c = vec![1.0f32; m * n];
        // SAFETY: a is m x k, b is k x n, c is m x n, row-major views of live vectors.
        unsafe {
            gemm(
                m,
                k,
                n,
                1.0,
                View { ptr: a.as_ptr(), rs: k as isize, cs: 1 },
                View { ptr: b.as_ptr(), rs: n as isize, cs: 1 },
                1.0,
                ViewMut { ptr: c.as_mut_ptr(), rs: n as isize, cs: 1 },
            );
        }
        for i in 0..m {
            for j in 0..n {
                let want: f32 = 1.0 + (0..k).map(|l| a[i * k + l] * b[l * n + j]).sum::<f32>();
                assert!((c[i * n + j] - want).abs() < 1e-4);
            }
        }
    }
}

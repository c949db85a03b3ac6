//! Output buffers of large batches, kept for the next call. A 100,000-sample PUMA base
//! regressor is 173 MB; a fresh allocation of that size comes from the kernel as untouched
//! pages, and faulting them in (zeroed) costs more than computing the output (≈ 250 ns/sample
//! against ≈ 120: README, `python/bench.py`). So an output of at least [`POOL_MIN_BYTES`] is a
//! Rust buffer lent to numpy; when the array dies, the buffer comes back here (at most
//! [`POOL_MAX_BUFFERS`], [`POOL_MAX_BYTES`] in all, the oldest making room) and the next call of the same size writes
//! into pages already mapped. The first call of a size still pays for fresh pages. Every value
//! of an output is written by the batch driver (the `out=` tests fill with NaN to check), so a
//! reused buffer's old contents never show.

use std::sync::Mutex;

use numpy::ndarray::{ArrayViewMutD, IxDyn};
use numpy::PyArrayDyn;
use pyo3::prelude::*;

/// Smallest output that goes through the pool (smaller ones are numpy's own arrays).
pub const POOL_MIN_BYTES: usize = 8 << 20;
/// Most buffers kept waiting.
pub const POOL_MAX_BUFFERS: usize = 2;
/// Most bytes kept waiting.
pub const POOL_MAX_BYTES: usize = 1 << 30;

static FREE: Mutex<Vec<Vec<f64>>> = Mutex::new(Vec::new());

/// The Python object that owns a lent buffer (the numpy array's base): gives it back on drop.
#[pyclass(frozen)]
struct LentBuffer {
    buf: Mutex<Option<Vec<f64>>>,
}

impl Drop for LentBuffer {
    fn drop(&mut self) {
        let buf = self.buf.get_mut().map(Option::take).unwrap_or(None);
        if let (Some(b), Ok(mut free)) = (buf, FREE.lock()) {
            if b.len() * 8 > POOL_MAX_BYTES {
                return;
            }
            // The newest stays; the oldest make room (freed after the lock is released).
            free.push(b);
            let mut evicted = Vec::new();
            while free.len() > POOL_MAX_BUFFERS
                || free.iter().map(|v| v.len() * 8).sum::<usize>() > POOL_MAX_BYTES
            {
                evicted.push(free.remove(0));
            }
            drop(free);
            drop(evicted);
        }
    }
}

/// A C-order float64 array of shape `dims` for an output, and whether its memory is fresh
/// (never written: see `Dynamics::run`'s `out_is_new`). At least [`POOL_MIN_BYTES`]: a pooled
/// buffer of that exact size if one waits, else a new one, lent to numpy either way.
pub fn output<'py>(
    py: Python<'py>,
    dims: &[usize],
) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, bool)> {
    let len: usize = dims.iter().product();
    if len * 8 < POOL_MIN_BYTES {
        return Ok((PyArrayDyn::<f64>::zeros(py, IxDyn(dims), false), true));
    }
    let reused = FREE.lock().ok().and_then(|mut free| {
        let k = free.iter().position(|v| v.len() == len)?;
        Some(free.swap_remove(k))
    });
    let fresh = reused.is_none();
    let mut buf = reused.unwrap_or_else(|| fresh_buffer(len));
    let ptr = buf.as_mut_ptr();
    let owner = Bound::new(
        py,
        LentBuffer {
            buf: Mutex::new(Some(buf)),
        },
    )?;
    // SAFETY: `ptr` points at `len` f64s owned by `owner`'s Vec, which is neither moved nor
    // resized while `owner` lives; `owner` becomes the array's base, so it lives as long as the
    // array (and every view of it).
    let array = unsafe {
        let view = ArrayViewMutD::from_shape_ptr(IxDyn(dims), ptr);
        PyArrayDyn::borrow_from_array(&view, owner.into_any())
    };
    Ok((array, fresh))
}

/// A zeroed buffer of `len` values; on Linux its pages are asked to be transparent huge pages
/// (as numpy does for its large arrays): faulting in 2 MB pages instead of 4 kB ones is what
/// makes a first call of a size ~2× cheaper.
fn fresh_buffer(len: usize) -> Vec<f64> {
    let mut buf = vec![0.0; len];
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 4096;
        let start = buf.as_mut_ptr() as usize;
        let end = start + len * std::mem::size_of::<f64>();
        let aligned = start.div_ceil(PAGE) * PAGE;
        if end > aligned {
            // SAFETY: the range lies inside `buf`'s allocation; madvise only advises the kernel
            // about pages nothing has touched yet (its failure changes nothing but speed).
            unsafe {
                libc::madvise(
                    aligned as *mut libc::c_void,
                    end - aligned,
                    libc::MADV_HUGEPAGE,
                );
            }
        }
    }
    buf
}

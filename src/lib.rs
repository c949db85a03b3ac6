//! dynid: D-H table -> generated dynamics kernels -> identification (work in progress).

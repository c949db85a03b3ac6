//! Embeds generated kernels (work in progress).

//! Integration tests of the linear algebra and its parallel paths: the sparse
//! saddle-point solver, the chain LDLᵀ and Newton-matrix assembly, the residual's
//! halves, allocation-free kernels, results independent of the thread count.

#[path = "../common/mod.rs"]
mod common;

// The counting global allocator of the allocation-free tests (one per binary).
#[path = "../common/counting.rs"]
mod counting;

mod chain_lu;
mod dense_pivoting;
mod determinism;
mod kernels;
mod newton_assembly;
mod parallel_newton;
mod residual_halves;
mod sparse_saddle;

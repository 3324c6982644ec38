//! Integration tests of the `mbsolve` binary: run, check, sweep, plot, animate,
//! view, study, streamed outputs, Arrow files, figures, bad input and the fuzz corpus.

#[path = "../common/mod.rs"]
mod common;

mod animate;
mod arrow;
mod bad_input;
mod check;
mod failure_messages;
mod figures;
mod fuzz_corpus;
mod outputs;
mod plot;
mod run;
mod sensors;
mod stream;
mod study;
mod sweep;
mod sweep_metrics;
mod view;

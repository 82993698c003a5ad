//! Integration tests of `moe-contact`: one binary, one module per concern.

mod common;
mod estimator;
mod fast_form;
mod gradients;
mod knn;
mod model_files;
mod reference;
mod training;

//! Evaluation: the Replica 3D instance metric of the paper (Open3DIS's
//! criterion).

pub mod instances;
pub mod replica;

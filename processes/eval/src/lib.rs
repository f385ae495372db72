//! harvest-eval: evaluations of the stack against the simulator's ground truth.

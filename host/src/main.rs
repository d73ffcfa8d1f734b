//! The `depthor` command line.
fn main() {}

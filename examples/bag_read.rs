//! Reads a ROS 2 bag of a 7-joint arm (`joint1..joint7`, as `tests/bags/make_bag.py synthetic`
//! writes it) into a [`dynid::log::Log`] and prints the rate; `benches/bag.sh` runs it under
//! `/usr/bin/time -v` for the peak memory.
//!
//!     cargo run --release --example bag_read -- BAG.mcap

use std::path::Path;
use std::time::Instant;

use dynid::bag::{self, BagOptions};

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: bag_read BAG.mcap");
        std::process::exit(2);
    };
    let opts = BagOptions {
        joints: Some((1..=7).map(|j| format!("joint{j}")).collect()),
        need_effort: true,
        ..BagOptions::default()
    };
    let start = Instant::now();
    let read = bag::read(Path::new(&path), 7, None, &opts).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(2)
    });
    let secs = start.elapsed().as_secs_f64();
    let log = read.log;
    // Read every row back (from the temporary file past the spill size) so the log is used.
    let mut sum = 0.0;
    log.rows(0, log.len(), |row| sum += row[1]);
    println!(
        "{path}: {} rows ({} values each) in {secs:.3} s: {:.0} messages/s; spilled to disk: {}; checksum {sum:.6}",
        log.len(),
        log.layout.width(),
        log.len() as f64 / secs,
        log.spilled()
    );
}

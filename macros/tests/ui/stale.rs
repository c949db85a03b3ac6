dynid_macros::arm!(stale, root = "tests/ui/fixtures");

fn main() {}

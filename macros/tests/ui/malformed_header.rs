dynid_macros::arm!(malformed, root = "tests/ui/fixtures");

fn main() {}

dynid_macros::arm!(mismatch, root = "tests/ui/fixtures");

fn main() {}

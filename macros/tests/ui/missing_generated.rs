dynid_macros::arm!(missing, root = "tests/ui/fixtures");

fn main() {}

dynid_macros::arm!(ghost, root = "tests/ui/fixtures");

fn main() {}

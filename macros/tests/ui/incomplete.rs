dynid_macros::arm!(incomplete, root = "tests/ui/fixtures");

fn main() {}

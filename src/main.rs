fn main() {
    println!("dynid: the paper reproduction is being built; see README.md");
}

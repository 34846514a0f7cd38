//! `slamesh`: LiDAR odometry and meshing from the command line (`slamesh --help`); each
//! subcommand lives in its own file under the library's `cli/`.

fn main() -> std::process::ExitCode {
    slamesh::cli::main()
}

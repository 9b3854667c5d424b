#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Installs every Debian (bookworm) package that fnmpc needs to build, test,
# benchmark and report. Idempotent; run as root (or with sudo available).
#   scripts/install-deps.sh            core + MuJoCo + Ceres + IPOPT + plotting + Python
#                                      module + browser replay (Node.js/npm, Chromium) +
#                                      campaigns (Slurm, munge, Dask, Optuna)
#   scripts/install-deps.sh --with-ros also the ROS 1 packages for ros/
#   scripts/install-deps.sh --with-ros2
#                                      also the DDS packages of the ROS 2 interface ros2/
#                                      (Cyclone DDS, Fast DDS, rosidl's .msg parser)
#   scripts/install-deps.sh --with-aarch64
#                                      also the aarch64 cross toolchain, qemu-user and the
#                                      arm64 libraries of the onboard layers (docs/onboard.md);
#                                      adds the arm64 architecture to dpkg
# The flags combine (e.g. --with-ros --with-ros2 --with-aarch64).
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libyaml-cpp-dev libcli11-dev libfmt-dev libspdlog-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libmujoco-dev
  libceres-dev coinor-libipopt-dev
  python3-matplotlib python3-numpy
  python3-dev pybind11-dev python3-pybind11 python3-pytest
  chromium python3-websocket
  slurm-wlm munge python3-dask python3-distributed python3-optuna python3-sqlalchemy python3-yaml
)
# Campaigns and tuning (docs/campaigns.md): Slurm 22.05 with munge for the single-node test
# cluster of scripts/slurm-local.sh (the packages' services are not started: no systemd
# needed), dask.distributed for the dask executor, Optuna with SQLAlchemy (its SQLite storage),
# PyYAML for the campaign file (tools/campaign.py).
# The replay viewer is bundled with npm (web/replay). Debian's nodejs and npm only when the
# machine has no Node.js of its own (a NodeSource nodejs ships npm and conflicts with
# Debian's npm package); bookworm's Node.js 18 runs the pinned esbuild (node >= 18).
if ! command -v node >/dev/null 2>&1; then packages+=(nodejs); fi
if ! command -v npm >/dev/null 2>&1; then packages+=(npm); fi
ros_packages=(
  libroscpp-dev libstd-msgs-dev libgeometry-msgs-dev libsensor-msgs-dev libnav-msgs-dev
  ros-std-msgs ros-geometry-msgs ros-sensor-msgs ros-nav-msgs
  python3-rosmaster python3-roslaunch rosout librostest-dev python3-rostest librosbag-dev catkin
  ros-message-generation python3-rosbag python3-rostopic python3-rosnode rosbash
  python3-geometry-msgs python3-sensor-msgs python3-nav-msgs libros-rosgraph-msgs-dev
)
# ROS 2 on DDS (ros2/, docs/ros2.md): Debian has no rclcpp, but it has the middleware ROS 2
# runs on. Cyclone DDS 0.10 with its IDL compiler idlc (cyclonedds-tools) for the nodes, Fast
# DDS 2.9 (libfastrtps-dev, libfastcdr-dev) for the test against an independent implementation,
# rosidl's .msg parser (python3-rosidl) for the .msg -> IDL conversion.
ros2_packages=(cyclonedds-dev cyclonedds-tools libfastrtps-dev libfastcdr-dev python3-rosidl)
# The onboard cross build (scripts/build-aarch64.sh): the compiler, the user-mode emulator that
# runs its tests, and the arm64 builds of the libraries with code (Eigen, CLI11 and
# nlohmann-json are header-only, Architecture: all, and come from the list above).
# libyaml-cpp-dev is not Multi-Arch: same, so its arm64 package would replace the build
# machine's: only the arm64 runtime library is installed, and build-aarch64.sh unpacks the
# arm64 -dev package into its build directory (apt-get download, dpkg-deb -x).
aarch64_packages=(
  g++-aarch64-linux-gnu qemu-user file
  libyaml-cpp0.7:arm64 libfmt-dev:arm64 libspdlog-dev:arm64 libgtest-dev:arm64 libgmock-dev:arm64
)
with_aarch64=0
for arg in "$@"; do
  case "$arg" in
    --with-ros) packages+=("${ros_packages[@]}") ;;
    --with-ros2) packages+=("${ros2_packages[@]}") ;;
    --with-aarch64) packages+=("${aarch64_packages[@]}"); with_aarch64=1 ;;
    *) echo "install-deps: unknown argument $arg" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all ${#packages[@]} packages already installed"
  exit 0
fi
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
if [[ $with_aarch64 -eq 1 ]] && ! dpkg --print-foreign-architectures | grep -qx arm64; then
  echo "install-deps: adding the arm64 architecture to dpkg"
  $SUDO dpkg --add-architecture arm64
fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"

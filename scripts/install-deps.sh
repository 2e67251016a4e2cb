#!/usr/bin/env bash
# Installs the Debian 12 packages photorig needs:
#   scripts/install-deps.sh demo   what `make demo` builds and runs: the photorig CLI and the
#                                  Python module (docs/dependencies.md, "The demo's packages")
#   scripts/install-deps.sh [test] everything: the whole tree, its tests, benchmarks and charts
# Runs as root, or through sudo otherwise. Safe to run again: apt-get skips what is present.
set -euo pipefail

demo_packages=(
  # toolchain
  build-essential cmake pkg-config
  # maths and images. OpenCV by module: libopencv-dev and libopencv-contrib-dev pull in every
  # module's -dev package (viz, dnn, videoio, ...); cmake/FindOpenCV.cmake finds these without it
  libeigen3-dev libopencv-core-dev libopencv-imgproc-dev libopencv-calib3d-dev
  # image files (solvers/codecs): PNG, TIFF, JPEG and OpenEXR on their reference libraries
  libpng-dev libtiff-dev libjpeg62-turbo-dev libopenexr-dev
  libceres-dev
  # relightable assets: glTF 2.0 writer/reader (header-only; its textures through solvers/codecs)
  libtinygltf-dev
  # data sets (DiLiGenT's ground truth is a MATLAB file)
  libmatio-dev
  # configuration, CLI, logging, serialisation
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  # daemon: HTTP API, persistent queue, systemd notification
  libcpp-httplib-dev libsqlite3-dev libsystemd-dev
  # devices: GenICam cameras, Modbus, GPIO, USB, V4L2 headers
  libaravis-dev libmodbus-dev libgpiod-dev libusb-1.0-0-dev linux-libc-dev
  # run store: vectorised CRC-32 and Adler-32 for frame files
  libdeflate-dev
  # NeXus export: the HDF5 C library (daemon/src/io/nexus.cpp)
  libhdf5-dev
  # `import photorig` (python/): pybind11 for the module, NumPy for its arrays
  pybind11-dev python3-dev python3-numpy
  # Brent's minimiser (Boost.Math, header-only) for the near-light depth search (solvers/ps)
  libboost-dev
)

test_packages=(
  # sources and the code-shape checks: function lengths (scripts/longest-functions.sh)
  git universal-ctags
  # OpenCV's CMake package, and contrib's mcc: the colour chart detector and colour-correction model
  libopencv-dev libopencv-contrib-dev
  # GenICam tools for the camera tests
  aravis-tools
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # an independent CRC-32 for the storage tests
  zlib1g-dev
  # V4L2 tests against the kernel's vivid driver in a VM (scripts/v4l2-vm-test.sh)
  qemu-system-x86 busybox-static cpio
  # charts (run under /usr/bin/python3)
  python3-matplotlib
  # the tomography peer: scikit-image's radon-transform reconstructions (scripts/chart-tomography.sh)
  python3-skimage
  # the low-frequency reflectance study on DiLiGenT objects: SciPy's NNLS and least squares
  # (scripts/diligent-low-frequency.py)
  python3-scipy
  # the browser interface's libraries, served by photorigd (docs/ui.md): three.js r111, Chart.js 3.9
  libjs-three libjs-chart.js
  # the browser interface's test: headless Chromium over WebDriver (tests/browser)
  chromium chromium-driver python3-selenium
  # ... which reads the canvases back as PNG (Pillow) and compares them with numpy
  python3-pil
  # ... NeXus export's test: h5py and OpenCV read the file and the frames back, nexus-tools' nxdir
  # and nxsummary are an independent reader (tests/daemon/check_nexus.py)
  python3-h5py python3-opencv nexus-tools
  # the Python module's tests and benchmark under pytest compare with frames read by OpenCV's own
  # Python binding (tests/python, bench/python)
  python3-pybind11 python3-pytest
  # fuzzers: libFuzzer, the sanitizer runtimes and clang's OpenMP (scripts/fuzz.sh)
  clang libclang-rt-14-dev libomp-14-dev
  # batch solves on Slurm: the tests start a single-node cluster (tests/slurm/slurm-node.sh, docs/scaling.md)
  slurm-wlm munge
  # tomography distributed over MPI processes (solvers/tomography_mpi, solve tomography --mpi, its mpirun test)
  libopenmpi-dev openmpi-bin
  # tomography's volume.vdb (daemon/src/io/vdb_volume.cpp); Debian's FindOpenVDB.cmake requires
  # Boost.Iostreams, which libopenvdb-dev does not pull in
  libopenvdb-dev libboost-iostreams-dev
)

case "${1:-test}" in
  demo) packages=("${demo_packages[@]}") ;;
  test) packages=("${demo_packages[@]}" "${test_packages[@]}") ;;
  *) echo "usage: scripts/install-deps.sh [demo|test]" >&2; exit 2 ;;
esac

if [ "$(id -u)" = 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
else
  echo "install-deps: run as root or install sudo" >&2
  exit 1
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
# munge's post-install script makes /etc/munge/munge.key with `su munge`, which
# fails where other users may not run /bin/sh (some containers) and stops the
# whole install. A key made here first lets it skip that step; the Slurm tests
# run munged with a key of their own.
if [[ " ${missing[*]} " == *" munge "* ]] && [ ! -e /etc/munge/munge.key ]; then
  "${as_root[@]}" install -d -m 0700 /etc/munge
  "${as_root[@]}" sh -c 'umask 0277 && head -c 1024 /dev/urandom > /etc/munge/munge.key'
fi
"${as_root[@]}" apt-get update -qq
"${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"

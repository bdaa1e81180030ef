#!/usr/bin/env bash
# One-time set-up of a fresh Debian machine with the Rust toolchain: installs the system packages
# the project builds against when they are missing (Open MPI for rsmpi, libclang for bindgen).
# With --tests, also what only the tests use: Debian's Chromium, which loads the study report as
# a person would, Valgrind, whose cachegrind counts instructions (`compare --instructions`),
# Python's vtk, whose readers open the solver's VTK files, pyarrow, which reads the Parquet
# tables as the guide's results chapter does, and cargo-nextest, which runs the tests. With
# --slurm, the packages of a single-node Slurm (scripts/slurm-local); --slurm-accounting adds its
# accounting (slurmdbd and MariaDB), --slurm-nodes what a cluster of network namespaces needs
# (iproute2).
# Cheap when everything is there, so `make run` and `make test` call it every time.
set -euo pipefail

for_tests=false
packages=(openmpi-bin libopenmpi-dev libclang-dev pkg-config)
for option in "$@"; do
  case "$option" in
    --tests) for_tests=true; packages+=(chromium valgrind) ;;
    # A single-node Slurm (scripts/slurm-local).
    --slurm) packages+=(munge slurmctld slurmd slurm-client) ;;
    --slurm-accounting) packages+=(slurmdbd mariadb-server) ;;
    --slurm-nodes) packages+=(iproute2) ;;
    *)
      echo "setup: unknown option $option" \
        "(the options are --tests, --slurm, --slurm-accounting and --slurm-nodes)" >&2
      exit 2
      ;;
  esac
done

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done

if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}" >&2
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup: need root (or sudo) to install ${missing[*]}" >&2; exit 1; }
    sudo=sudo
  fi
  # Without systemd, a package's maintainer script starts its system service (MariaDB on port
  # 3306, slurmdbd without a configuration) through invoke-rc.d wherever init is in a runlevel;
  # scripts/slurm-local starts its own daemons, so deny those starts while installing, the way
  # Debian's container images do.
  policy=/usr/sbin/policy-rc.d
  if [ ! -d /run/systemd/system ] && [ ! -e "$policy" ]; then
    trap '$sudo rm -f "$policy"' EXIT
    printf '#!/bin/sh\nexit 101\n' | $sudo tee "$policy" >/dev/null
    $sudo chmod 755 "$policy"
  fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# Python's vtk opens the solver's VTK files and pyarrow the Parquet tables, as users do.
if $for_tests && ! python3 -c "import vtkmodules.vtkIOXML, pyarrow.parquet" 2>/dev/null; then
  command -v python3 >/dev/null || { echo "setup: python3 not found; the tests read VTK files with Python's vtk and tables with pyarrow" >&2; exit 1; }
  echo "setup: installing Python's vtk and pyarrow (pip)" >&2
  python3 -m pip install --quiet --root-user-action=ignore vtk pyarrow
fi

command -v cargo >/dev/null || { echo "setup: cargo not found; install the Rust toolchain (rustup)" >&2; exit 1; }

# cargo-nextest runs the tests of every test binary in one pool (scripts/run-tests); machines of
# this kind have it, and elsewhere it is built from crates.io once.
if $for_tests && ! cargo nextest --version >/dev/null 2>&1; then
  echo "setup: installing cargo-nextest (cargo install)" >&2
  cargo install --locked --quiet cargo-nextest
fi

# Cross build for arm64 (Raspberry Pi 3/4/5 with a 64-bit OS) with Debian's multiarch packages:
# crossbuild-essential-arm64 (aarch64-linux-gnu-gcc/g++), the arm64 -dev packages of every library
# (tools/install-deps.sh --arm64) in /usr/lib/aarch64-linux-gnu, headers in /usr/include (shared with
# the native packages), and qemu-user-static to run what was built (tests). Preset `arm64`
# (build-arm64/): ./run package arm64, ./run test-arm64.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(LOCUS_CROSS_TRIPLE aarch64-linux-gnu)

set(CMAKE_C_COMPILER ${LOCUS_CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${LOCUS_CROSS_TRIPLE}-g++)
# Multiarch, no sysroot: find_package/find_library look in lib/aarch64-linux-gnu (never in the
# native lib/x86_64-linux-gnu), pkg-config reads only the arm64 .pc files.
set(CMAKE_LIBRARY_ARCHITECTURE ${LOCUS_CROSS_TRIPLE})
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/${LOCUS_CROSS_TRIPLE}/pkgconfig:/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

# Programs built here run under qemu (gtest_discover_tests, ctest, try_run). The arm64 loader and
# libraries are where multiarch put them (/lib/ld-linux-aarch64.so.1, /usr/lib/aarch64-linux-gnu).
find_program(LOCUS_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(LOCUS_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${LOCUS_QEMU_AARCH64})
endif()

# libyaml-cpp-dev is not Multi-Arch: same (its arm64 package would remove the native one), so the
# arm64 build uses the native package's headers (/usr/include/yaml-cpp, architecture-independent) and
# the arm64 runtime library (libyaml-cpp0.7:arm64) through a small config package.
if(NOT EXISTS /usr/lib/${LOCUS_CROSS_TRIPLE}/cmake/yaml-cpp/yaml-cpp-config.cmake)
  set(yaml-cpp_DIR ${CMAKE_CURRENT_LIST_DIR}/aarch64-yaml-cpp CACHE PATH "yaml-cpp for arm64 (toolchain)")
endif()

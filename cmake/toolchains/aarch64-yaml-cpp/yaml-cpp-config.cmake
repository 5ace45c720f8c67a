# yaml-cpp for the arm64 cross build (cmake/toolchains/aarch64-linux-gnu.cmake): the headers of the
# native libyaml-cpp-dev, the library of libyaml-cpp0.7:arm64 (no arm64 -dev package beside the native
# one: it is not Multi-Arch: same).
file(GLOB _locus_yaml_lib /usr/lib/aarch64-linux-gnu/libyaml-cpp.so.0.*)
if(NOT _locus_yaml_lib OR NOT EXISTS /usr/include/yaml-cpp/yaml.h)
  set(yaml-cpp_FOUND FALSE)
  set(yaml-cpp_NOT_FOUND_MESSAGE "needs libyaml-cpp0.7:arm64 and libyaml-cpp-dev (tools/install-deps.sh --arm64)")
  return()
endif()
list(GET _locus_yaml_lib 0 _locus_yaml_lib)
if(NOT TARGET yaml-cpp)
  add_library(yaml-cpp SHARED IMPORTED)
  # the headers are in /usr/include, which the cross compiler searches already (multiarch)
  set_target_properties(yaml-cpp PROPERTIES IMPORTED_LOCATION ${_locus_yaml_lib})
endif()
set(yaml-cpp_FOUND TRUE)

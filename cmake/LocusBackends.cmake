# Optional backends: LOCUS_WITH_<X> for JACK, ALSA, BLUEZ (sdbus-c++), MQTT (libmosquitto) and HTTP
# (cpp-httplib: the live map of locusd --http).
#
# Why: a board may lack some of these libraries (no JACK server, no BlueZ), and the rest of Locus does
# not need them. Like PipeWire's SPA, each backend is built when its dependency is there:
#   AUTO (default)  build it when pkg-config finds the library, skip it quietly otherwise;
#   ON              required: configuring fails with a message naming the library and its Debian package;
#   OFF             never built, even when the library is installed.
# The `default` preset (what ./run and CI build) sets all of them ON, so CI cannot lose a backend without
# failing; the `minimal` preset sets them OFF (CMakePresets.json).
#
# For each backend <X> this sets, in the caller's scope:
#   LOCUS_HAVE_<X>      TRUE/FALSE: whether the backend is built (CMake conditions on code and tests)
#   LOCUS_WHY_NO_<X>    why not ("LOCUS_WITH_JACK=OFF", "LOCUS_WITH_JACK=AUTO and libjack not found ...")
# and the imported target PkgConfig::<PREFIX> when built. locus_write_build_options() then writes the
# generated header locus/build_options.hpp (interface target locus_build_options): LOCUS_HAVE_<X> macros
# and the table the host uses to say "JACK support was not built in (...)" (config errors, `locus
# devices`, `locus plugins`, `locus version`).

# locus_optional_backend(<X> PREFIX <pkg prefix> PKG <pkg-config module> LIBRARY <name> DEB <package>
#                        DOC <what it is>)
function(locus_optional_backend id)
  cmake_parse_arguments(A "" "PREFIX;PKG;LIBRARY;DEB;DOC" "" ${ARGN})
  set(opt LOCUS_WITH_${id})
  set(${opt} AUTO CACHE STRING "${A_DOC}: AUTO (built when ${A_LIBRARY} is found), ON (required) or OFF")
  set_property(CACHE ${opt} PROPERTY STRINGS AUTO ON OFF)
  string(TOUPPER "${${opt}}" mode)
  if(mode MATCHES "^(ON|YES|TRUE|Y|1)$")
    set(mode ON)
  elseif(mode MATCHES "^(OFF|NO|FALSE|N|0)$")
    set(mode OFF)
  elseif(NOT mode STREQUAL "AUTO")
    message(FATAL_ERROR "${opt}='${${opt}}': expected AUTO, ON or OFF")
  endif()

  set(have FALSE)
  set(why "")
  if(mode STREQUAL "OFF")
    set(why "${opt}=OFF")
  else()
    pkg_check_modules(${A_PREFIX} QUIET IMPORTED_TARGET GLOBAL ${A_PKG})
    if(${A_PREFIX}_FOUND)
      set(have TRUE)
    elseif(mode STREQUAL "ON")
      message(FATAL_ERROR
        "${opt}=ON but ${A_LIBRARY} was not found (pkg-config module '${A_PKG}', Debian package ${A_DEB}). "
        "Install it (tools/install-deps.sh installs every dependency), or configure with "
        "-D${opt}=AUTO (build ${id} support only when found) or -D${opt}=OFF (without ${id} support).")
    else()
      set(why "${opt}=AUTO and ${A_LIBRARY} not found: pkg-config module '${A_PKG}', Debian package ${A_DEB}")
    endif()
  endif()
  if(have)
    message(STATUS "Locus backend ${id}: built in (${opt}=${mode}, ${A_PKG} ${${A_PREFIX}_VERSION})")
  else()
    message(STATUS "Locus backend ${id}: NOT built in (${why})")
  endif()
  set(LOCUS_HAVE_${id} ${have} PARENT_SCOPE)
  set(LOCUS_WHY_NO_${id} "${why}" PARENT_SCOPE)
endfunction()

# Writes ${CMAKE_BINARY_DIR}/generated/locus/build_options.hpp from cmake/build_options.hpp.in and
# defines the interface target locus_build_options that puts it on the include path. Only the files
# that ask which backends exist include it (hal/builtin.cpp, link/links.cpp, tools, tests), so
# switching a backend rebuilds those alone.
function(locus_write_build_options)
  foreach(id JACK ALSA BLUEZ MQTT HTTP)
    if(LOCUS_HAVE_${id})
      set(LOCUS_HAVE_${id}_01 1)
      set(LOCUS_HAVE_${id}_BOOL true)
    else()
      set(LOCUS_HAVE_${id}_01 0)
      set(LOCUS_HAVE_${id}_BOOL false)
    endif()
  endforeach()
  configure_file(${PROJECT_SOURCE_DIR}/cmake/build_options.hpp.in
                 ${CMAKE_BINARY_DIR}/generated/locus/build_options.hpp @ONLY)
  add_library(locus_build_options INTERFACE)
  target_include_directories(locus_build_options INTERFACE ${CMAKE_BINARY_DIR}/generated)
endfunction()

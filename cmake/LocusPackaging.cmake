# Debian packages (CPack DEB), built by `./run package` (amd64, and arm64 by a cross build; `./run package amd64|arm64` for one):
#   locus      locusd, locus, liblocus.so.0 (the built-in plugins are linked into locusd/locus), the
#              configs (/etc/locus/*.yaml as conffiles, every shipped config in /usr/share/locus/config),
#              the systemd template unit locus@.service and the maintainer scripts creating the `locus`
#              system user (packaging/debian). Depends: from dpkg-shlibdeps, plus adduser.
#   locus-dev  the plugin API headers, liblocus.so and the CMake package (find_package(Locus)).
# Paths are those of the installed system (prefix /usr); the unit and the configs use absolute paths.
# tests/integration/package unpacks the package into a scratch root, replays a scene with its binaries
# and verifies its unit (systemd-analyze verify).

# cpack (and `ninja install`) install what is built without building `all` first: ./run package builds
# only locusd, locus and liblocus (not the tests), and the package test runs cpack inside ctest.
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)

set(LOCUS_ETC_DIR /etc/locus)
set(LOCUS_SHARE_DIR ${CMAKE_INSTALL_DATADIR}/locus)

# Configs: the board configs a service instance runs (locus@<name> reads /etc/locus/<name>.yaml) in
# /etc/locus; all shipped configs (demo, replay, per-system) as references in /usr/share/locus/config.
# The /etc directory is chosen when installing, as GNUInstallDirs' FULL_SYSCONFDIR would: /etc/locus for
# the prefix /usr (the packages: CPack installs with DESTDIR and the prefix /usr), <prefix>/etc/locus
# for any other (`cmake --install build --prefix DIR`, as tests/integration/out_of_tree does, never
# writes into the real /etc).
set(LOCUS_ETC_CONFIGS board.yaml jack-node.yaml pi-2mic-hat.yaml pi-usb-mic.yaml)
list(TRANSFORM LOCUS_ETC_CONFIGS PREPEND ${PROJECT_SOURCE_DIR}/config/)
install(CODE "
  if(CMAKE_INSTALL_PREFIX STREQUAL \"/usr\")
    set(locus_etc \"${LOCUS_ETC_DIR}\")
  else()
    set(locus_etc \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_SYSCONFDIR}/locus\")
  endif()
  file(INSTALL DESTINATION \"\${locus_etc}\" TYPE FILE FILES ${LOCUS_ETC_CONFIGS})
" COMPONENT runtime)
file(GLOB LOCUS_ALL_CONFIGS CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/config/*.yaml)
install(FILES ${LOCUS_ALL_CONFIGS} DESTINATION ${LOCUS_SHARE_DIR}/config COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/packaging/systemd/locus@.service
        DESTINATION lib/systemd/system COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/README.md ${PROJECT_SOURCE_DIR}/docs/raspberry-pi.md
              ${PROJECT_SOURCE_DIR}/docs/config.md ${PROJECT_SOURCE_DIR}/docs/hal-alsa.md
              ${PROJECT_SOURCE_DIR}/docs/events.md
        DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/locus COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/packaging/mosquitto/locus.acl ${PROJECT_SOURCE_DIR}/docs/mqtt.md
        DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/locus/examples COMPONENT runtime)

# conffiles: every file installed under /etc (dpkg keeps a user's edits on upgrade).
set(LOCUS_CONFFILES "")
foreach(cfg ${LOCUS_ETC_CONFIGS})
  get_filename_component(name ${cfg} NAME)
  string(APPEND LOCUS_CONFFILES "${LOCUS_ETC_DIR}/${name}\n")
endforeach()
file(WRITE ${CMAKE_BINARY_DIR}/packaging/conffiles "${LOCUS_CONFFILES}")

# Debian architecture of the target: dpkg's own for a native build, mapped from the toolchain's
# processor for a cross build (cmake/toolchains/aarch64-linux-gnu.cmake).
if(CMAKE_CROSSCOMPILING)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
    set(LOCUS_DEB_ARCH arm64)
  elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(armv7|arm)")
    set(LOCUS_DEB_ARCH armhf)
  else()
    set(LOCUS_DEB_ARCH ${CMAKE_SYSTEM_PROCESSOR})
  endif()
else()
  find_program(LOCUS_DPKG dpkg)
  if(LOCUS_DPKG)
    execute_process(COMMAND ${LOCUS_DPKG} --print-architecture OUTPUT_VARIABLE LOCUS_DEB_ARCH
                    OUTPUT_STRIP_TRAILING_WHITESPACE)
  else()
    set(LOCUS_DEB_ARCH ${CMAKE_SYSTEM_PROCESSOR})
  endif()
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME locus)
set(CPACK_PACKAGE_VENDOR "Locus")
set(CPACK_PACKAGE_CONTACT "Locus maintainers <locus@localhost>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "real-time localization from sound, motion and Bluetooth")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_SET_DESTDIR ON)  # install with DESTDIR=<staging> and the prefix /usr (see /etc above)
set(CPACK_PACKAGE_DIRECTORY ${CMAKE_BINARY_DIR}/packages)
set(CPACK_STRIP_FILES ON)
set(CPACK_THREADS 0)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL runtime dev)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${LOCUS_DEB_ARCH})
set(CPACK_DEBIAN_PACKAGE_SECTION sound)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://example.invalid/locus")

set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME locus)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_RUNTIME_PACKAGE_RECOMMENDS "alsa-utils")
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SUGGESTS "bluez, jackd2, mosquitto")
set(CPACK_DEBIAN_RUNTIME_PACKAGE_CONTROL_EXTRA
    ${CMAKE_BINARY_DIR}/packaging/conffiles
    ${PROJECT_SOURCE_DIR}/packaging/debian/postinst
    ${PROJECT_SOURCE_DIR}/packaging/debian/prerm
    ${PROJECT_SOURCE_DIR}/packaging/debian/postrm)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_COMPONENT_RUNTIME_DESCRIPTION
    "Locus localizes devices, people and Bluetooth tags from sound, motion and radio on Raspberry Pi
class boards. This package holds the daemon (locusd), the command-line tool (locus) with the built-in
plugins, the board configs in /etc/locus and the systemd template unit locus@.service: a node per
config, `systemctl start locus@board` runs /etc/locus/board.yaml as the locus user.")

set(CPACK_DEBIAN_DEV_PACKAGE_NAME locus-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "locus (= ${PROJECT_VERSION})")
set(CPACK_COMPONENT_DEV_DESCRIPTION
    "The Locus plugin API (headers, liblocus.so and the CMake package Locus::api) for building
detector and localizer plugins out of tree.")

include(CPack)

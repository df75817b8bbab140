# Debian packages through CPack: `cpack -G DEB` in a build folder configured with
# -DCMAKE_INSTALL_PREFIX=/usr (scripts/test-packages shows the whole route).
#   softshock-client  the `softshock` CLI and the Python package softshock_client (+ stubs)
#   softshockd        the daemon, softshock-mesh (its Gmsh meshing process), softshock-solve
#                     and a systemd unit (full builds only)
# Library dependencies come from dpkg-shlibdeps; the Python modules the client imports are
# declared by hand (they are not linked).
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME softshock)
set(CPACK_PACKAGE_VENDOR softshock)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "softshock maintainers <softshock@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "shock waves in soft solids: solver service and clients")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # softshock-client_0.1.0_amd64.deb
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_SECTION science)

set(CPACK_DEBIAN_CLIENT_PACKAGE_NAME softshock-client)
set(CPACK_COMPONENT_CLIENT_DESCRIPTION
    "softshock command-line and Python clients of softshockd\n The softshock CLI submits and follows simulations, reads results and grids; the\n Python package softshock_client does the same from scripts and notebooks.")
set(CPACK_DEBIAN_CLIENT_PACKAGE_DEPENDS "python3, python3-grpcio, python3-protobuf, python3-numpy")
set(CPACK_DEBIAN_CLIENT_PACKAGE_RECOMMENDS "python3-matplotlib")
set(CPACK_DEBIAN_CLIENT_PACKAGE_SUGGESTS "python3-xarray, python3-h5py")

set(CPACK_DEBIAN_DAEMON_PACKAGE_NAME softshockd)
set(CPACK_COMPONENT_DAEMON_DESCRIPTION
    "softshock simulation daemon\n softshockd runs shock-wave simulations of soft solids submitted over gRPC, with a\n SQLite catalogue and HDF5/XDMF results; softshock-solve runs one spec without it.")
set(CPACK_DEBIAN_DAEMON_PACKAGE_SUGGESTS "softshock-client, paraview")

# Each package: its man pages (packaging/man.cmake), a DEP-5 copyright file; the client's bash
# completion; the daemon's deployment guide, which the unit's Documentation= names.
include(${CMAKE_CURRENT_LIST_DIR}/man.cmake)
softshock_man_page(softshock 1 client "command-line client of the softshock daemon")
install(FILES ${PROJECT_SOURCE_DIR}/packaging/copyright DESTINATION share/doc/softshock-client
        COMPONENT client)
install(FILES ${PROJECT_SOURCE_DIR}/packaging/softshock.bash-completion
        DESTINATION share/bash-completion/completions RENAME softshock COMPONENT client)
if(SOFTSHOCK_CLIENT_ONLY)
  set(CPACK_COMPONENTS_ALL client)
else()
  set(CPACK_COMPONENTS_ALL client daemon)
  install(FILES ${PROJECT_SOURCE_DIR}/packaging/softshockd.service
          DESTINATION lib/systemd/system COMPONENT daemon)
  softshock_man_page(softshockd 8 daemon "softshock simulation daemon (gRPC)")
  softshock_man_page(softshock-solve 1 daemon "run one softshock spec without the daemon")
  softshock_man_page(softshock-mesh 1 daemon "mesh a softshock spec (softshockd's meshing process)")
  install(FILES ${PROJECT_SOURCE_DIR}/packaging/copyright ${PROJECT_SOURCE_DIR}/docs/deploy.md
          DESTINATION share/doc/softshockd COMPONENT daemon)
endif()
include(CPack)

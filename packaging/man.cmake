# Man pages, generated at build time by Debian's help2man from each program's own --help and
# --version (so they cannot drift from them), plus a SEE ALSO section from packaging/man/*.h2m;
# gzipped (-9n, reproducible) for share/man/manN as Debian policy wants.
#   softshock_man_page(TARGET SECTION COMPONENT "one-line description")
find_program(SOFTSHOCK_HELP2MAN help2man)
if(NOT SOFTSHOCK_HELP2MAN)
  message(WARNING "help2man not found: the packages get no man pages (scripts/install-deps)")
endif()

function(softshock_man_page target section component description)
  if(NOT SOFTSHOCK_HELP2MAN)
    return()
  endif()
  set(_page ${CMAKE_BINARY_DIR}/man/${target}.${section})
  set(_include ${PROJECT_SOURCE_DIR}/packaging/man/${target}.h2m)
  add_custom_command(
    OUTPUT ${_page}.gz
    COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_BINARY_DIR}/man
    COMMAND ${SOFTSHOCK_HELP2MAN} --no-info
            --section=${section} --name=${description} --include=${_include}
            --output=${_page} $<TARGET_FILE:${target}>
    COMMAND gzip -9nf ${_page}
    DEPENDS ${target} ${_include}
    COMMENT "Man page ${target}(${section}) from its --help"
    VERBATIM)
  add_custom_target(${target}_man ALL DEPENDS ${_page}.gz)
  install(FILES ${_page}.gz DESTINATION share/man/man${section} COMPONENT ${component})
endfunction()

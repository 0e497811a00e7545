# FindCHOLMOD.cmake - SuiteSparse CHOLMOD (Debian's SuiteSparse 5 ships no CMake config).
#
# Defines CHOLMOD_FOUND, CHOLMOD_INCLUDE_DIR, CHOLMOD_LIBRARIES and the imported
# target CHOLMOD::CHOLMOD. CHOLMOD's own dependencies (suitesparseconfig, amd,
# colamd, camd, ccolamd) are linked too, since the static and some shared
# builds do not pull them in by themselves.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY cholmod)
find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig)
foreach(_dep amd colamd camd ccolamd)
  string(TOUPPER ${_dep} _DEP)
  find_library(${_DEP}_LIBRARY ${_dep})
  if(${_DEP}_LIBRARY)
    list(APPEND _cholmod_deps ${${_DEP}_LIBRARY})
  endif()
endforeach()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(CHOLMOD
  REQUIRED_VARS CHOLMOD_LIBRARY CHOLMOD_INCLUDE_DIR SUITESPARSECONFIG_LIBRARY)

if(CHOLMOD_FOUND AND NOT TARGET CHOLMOD::CHOLMOD)
  set(CHOLMOD_LIBRARIES ${CHOLMOD_LIBRARY} ${_cholmod_deps} ${SUITESPARSECONFIG_LIBRARY})
  add_library(CHOLMOD::CHOLMOD INTERFACE IMPORTED)
  set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${CHOLMOD_LIBRARIES}")
endif()
mark_as_advanced(CHOLMOD_INCLUDE_DIR CHOLMOD_LIBRARY SUITESPARSECONFIG_LIBRARY)

# FindTetGen
# ----------
# Finds TetGen 1.5 (Debian: libtet1.5-dev) and defines the imported target TetGen::TetGen.
# TETLIBRARY is put on the target's interface so every translation unit sees the library API
# (tetrahedralize(char*, ...)) and TetGen reports errors by throwing an int instead of exiting.
#
# Result variables: TetGen_FOUND, TetGen_INCLUDE_DIR, TetGen_LIBRARY.
find_path(TetGen_INCLUDE_DIR NAMES tetgen.h PATH_SUFFIXES tetgen)
find_library(TetGen_LIBRARY NAMES tet tetgen)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(TetGen REQUIRED_VARS TetGen_LIBRARY TetGen_INCLUDE_DIR)
if(TetGen_FOUND AND NOT TARGET TetGen::TetGen)
  add_library(TetGen::TetGen UNKNOWN IMPORTED)
  set_target_properties(TetGen::TetGen PROPERTIES
    IMPORTED_LOCATION "${TetGen_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${TetGen_INCLUDE_DIR}"
    INTERFACE_COMPILE_DEFINITIONS "TETLIBRARY")
endif()
mark_as_advanced(TetGen_INCLUDE_DIR TetGen_LIBRARY)

# SPDX-License-Identifier: Apache-2.0
# Finds levelforge's dependencies from the Debian packages. Used by the build and by the
# installed levelforgeConfig.cmake, so downstream projects get the same targets.
include(CMakeFindDependencyMacro)

# Debian ships OpenVDB's FindOpenVDB.cmake in a multiarch folder, not a config package.
foreach(_dir /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB /usr/lib/x86_64-linux-gnu/cmake/OpenVDB
             /usr/lib/aarch64-linux-gnu/cmake/OpenVDB /usr/local/lib/cmake/OpenVDB)
  if(EXISTS "${_dir}/FindOpenVDB.cmake")
    list(APPEND CMAKE_MODULE_PATH "${_dir}")
    break()
  endif()
endforeach()

find_dependency(TBB)
find_dependency(OpenVDB)
if(NOT TARGET OpenVDB::openvdb)
  message(FATAL_ERROR "OpenVDB not found: install libopenvdb-dev (scripts/setup does it)")
endif()
if(NOT LEVELFORGE_FIND_DEPENDENCIES_FOR_CONSUMER)
  find_dependency(OpenMesh)
endif()

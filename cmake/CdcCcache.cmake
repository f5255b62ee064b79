# Use ccache for C and C++ when it is installed (and not already chosen by the user).
find_program(CDC_CCACHE ccache)
if(CDC_CCACHE AND NOT CMAKE_CXX_COMPILER_LAUNCHER)
  set(CMAKE_C_COMPILER_LAUNCHER "${CDC_CCACHE}" CACHE STRING "" FORCE)
  set(CMAKE_CXX_COMPILER_LAUNCHER "${CDC_CCACHE}" CACHE STRING "" FORCE)
  message(STATUS "cdc: using ccache (${CDC_CCACHE})")
endif()

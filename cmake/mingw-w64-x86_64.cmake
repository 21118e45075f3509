# Cross-compile rbcloth for 64-bit Windows with Debian's mingw-w64 (package
# gcc-mingw-w64-x86-64):
#   cmake -S . -B build-win -DCMAKE_TOOLCHAIN_FILE=cmake/mingw-w64-x86_64.cmake \
#         -DRBC_BUILD_EXTRAS=OFF
# The -posix compiler is the one with winpthreads (the core's thread pool uses
# pthreads); the -win32 flavour has no <pthread.h>.
set(CMAKE_SYSTEM_NAME Windows)
set(CMAKE_SYSTEM_PROCESSOR x86_64)
set(RBC_MINGW_TRIPLE x86_64-w64-mingw32)

set(CMAKE_C_COMPILER ${RBC_MINGW_TRIPLE}-gcc-posix)
set(CMAKE_CXX_COMPILER ${RBC_MINGW_TRIPLE}-g++-posix)
set(CMAKE_RC_COMPILER ${RBC_MINGW_TRIPLE}-windres)
# Debian installs the mingw-w64 runtime (headers, import libraries, winpthreads)
# under /usr/x86_64-w64-mingw32: search there for libraries and headers only, never
# in the host's /usr (a Linux library must not be picked up), and run programs
# (generators, pkg-config) from the host.
set(CMAKE_FIND_ROOT_PATH /usr/${RBC_MINGW_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# rbcloth.dll must need only Windows' own DLLs: libgcc (its unwinder and helpers)
# and winpthreads are linked in statically, so no libgcc_s_seh-1.dll or
# libwinpthread-1.dll has to be shipped beside it. -static makes the linker take
# libwinpthread.a instead of its import library (the system import libraries,
# kernel32 and msvcrt, have no static form and stay DLL imports).
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-static-libgcc -static")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-static-libgcc -static")
set(CMAKE_MODULE_LINKER_FLAGS_INIT "-static-libgcc -static")

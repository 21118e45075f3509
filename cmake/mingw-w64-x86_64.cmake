# Cross-compile rbcloth for 64-bit Windows with Debian's mingw-w64 (package
# gcc-mingw-w64-x86-64):
#   cmake -S . -B build-win -DCMAKE_TOOLCHAIN_FILE=cmake/mingw-w64-x86_64.cmake \
#         -DRBC_BUILD_EXTRAS=OFF
# The -win32 flavour (GCC's thread model win32): the library's threads are Win32's
# own (core/threads.h), and neither it nor this compiler's libgcc needs winpthreads,
# which the -posix flavour links into every program. Debian installs winpthreads'
# headers for both flavours, so <pthread.h> still compiles; the link is the proof:
# this compiler does not link libwinpthread, so a pthread_* call (or clock_gettime,
# winpthreads' too) is an undefined reference and the build fails.
set(CMAKE_SYSTEM_NAME Windows)
set(CMAKE_SYSTEM_PROCESSOR x86_64)
set(RBC_MINGW_TRIPLE x86_64-w64-mingw32)

set(CMAKE_C_COMPILER ${RBC_MINGW_TRIPLE}-gcc-win32)
set(CMAKE_CXX_COMPILER ${RBC_MINGW_TRIPLE}-g++-win32)
set(CMAKE_RC_COMPILER ${RBC_MINGW_TRIPLE}-windres)
# Debian installs the mingw-w64 runtime (headers, import libraries)
# under /usr/x86_64-w64-mingw32: search there for libraries and headers only, never
# in the host's /usr (a Linux library must not be picked up), and run programs
# (generators, pkg-config) from the host.
set(CMAKE_FIND_ROOT_PATH /usr/${RBC_MINGW_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# rbcloth.dll must need only Windows' own DLLs: libgcc (its unwinder and helpers)
# is linked in statically, so no libgcc_s_seh-1.dll has to be shipped beside it.
# (No -static: winpthreads, which it used to take as libwinpthread.a, is gone, and
# the system's import libraries have no static form anyway.)
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-static-libgcc")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-static-libgcc")
set(CMAKE_MODULE_LINKER_FLAGS_INIT "-static-libgcc")

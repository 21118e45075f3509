# Sanitizer and fuzzing builds (tests/README.md, "Sanitizers and fuzzing").
#
#   RBC_SANITIZE=address,undefined   every target (core, plugin, CLI, tests) built
#                                    with ASan + UBSan; `make check-asan`
#   RBC_SANITIZE=thread              ThreadSanitizer, with clang (CC=clang-14);
#                                    `make check-tsan` runs `ctest -L threads`
#   RBC_FUZZ=ON                      the libFuzzer targets of tests/fuzz (clang only);
#                                    usually with RBC_SANITIZE=address,undefined
#
# Empty RBC_SANITIZE and RBC_FUZZ OFF (the default) change nothing in the build.
set(RBC_SANITIZE "" CACHE STRING
    "Sanitizers for every target, as -fsanitize= takes them (address,undefined or thread); empty: none")
option(RBC_FUZZ "Build the libFuzzer targets of tests/fuzz (needs clang)" OFF)
# core/simd.h's target_clones make ifunc resolvers, which gcc's TSan crashes on inside
# dlopen (docs/facts.md). simd.h (and bench/perf.c) already leave the
# clones out under clang, the compiler of the TSan and fuzz builds, so no switch is
# needed: those builds run the "default" clone's code. gcc's ASan+UBSan build keeps
# the clones (the code that ships).
if(RBC_SANITIZE MATCHES "thread" AND NOT CMAKE_C_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "RBC_SANITIZE=thread needs clang (CC=clang-14): gcc's TSan crashes "
    "in dlopen on the plugin's target_clones ifunc resolvers (docs/facts.md)")
endif()
if(RBC_FUZZ AND NOT CMAKE_C_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "RBC_FUZZ needs clang with libFuzzer (CC=clang-14, libclang-rt-14-dev)")
endif()

if(RBC_SANITIZE)
  message(STATUS "rbcloth: sanitizers ${RBC_SANITIZE} on every target")
  add_compile_options(-fsanitize=${RBC_SANITIZE} -fno-omit-frame-pointer)
  add_link_options(-fsanitize=${RBC_SANITIZE})
  if(RBC_SANITIZE MATCHES "undefined")
    # Undefined behaviour is an error (exit status, stack), not a line in the log.
    add_compile_options(-fno-sanitize-recover=undefined)
  endif()
  if(RBC_SANITIZE MATCHES "address|leak")
    # LeakSanitizer and libgomp (tests/sanitizers/lsan.supp says why not a suppression):
    # libcholmod.so.3 (core/direct.c's CHOLMOD) needs libgomp.so.1, whose constructor
    # (initialize_env -> gomp_init_num_threads) mallocs gomp_cpusetp, 8 bytes kept in a
    # libgomp global for the life of the library. A host that dlopens the plugin and
    # dlcloses it (the CLI, test_abi_conformance, test_scene_world) unmaps libgomp
    # with that global, and LeakSanitizer reports the block at exit as a direct leak
    # from "<unknown module>". Every executable of these builds therefore links
    # libgomp itself, so it stays loaded (as in any host that uses OpenMP) and the
    # block stays reachable: nothing of ours is hidden from the leak checker.
    find_library(RBC_GOMP_LIBRARY NAMES libgomp.so.1 gomp)
    if(RBC_GOMP_LIBRARY)
      add_link_options("LINKER:--push-state,--no-as-needed" ${RBC_GOMP_LIBRARY}
                       "LINKER:--pop-state")
    endif()
  endif()
  # The ASan builds already are what import_sweep_asan builds on the side, and
  # -fsanitize=address cannot be combined with thread.
  if(NOT DEFINED RBC_IMPORT_ASAN)
    set(RBC_IMPORT_ASAN OFF CACHE BOOL "Build and run the import sweep with AddressSanitizer")
  endif()
endif()
if(RBC_FUZZ)
  message(STATUS "rbcloth: libFuzzer targets (tests/fuzz), coverage on every target")
  add_compile_options(-fsanitize=fuzzer-no-link)
  if(NOT DEFINED RBC_IMPORT_ASAN)
    set(RBC_IMPORT_ASAN OFF CACHE BOOL "Build and run the import sweep with AddressSanitizer")
  endif()
endif()

# clang does not link a sanitizer runtime into shared libraries (the executable
# carries it and exports its symbols), so the plugin's -Wl,--no-undefined
# (plugin/CMakeLists.txt) would refuse the __asan_/__tsan_ references. At the end
# of the top directory, once every target exists, each shared library gets
# -Wl,-z,undefs after its own options (the last of the two wins).
function(_rbc_sanitize_allow_undefined dir)
  get_property(targets DIRECTORY ${dir} PROPERTY BUILDSYSTEM_TARGETS)
  foreach(t IN LISTS targets)
    get_target_property(type ${t} TYPE)
    if(type STREQUAL "SHARED_LIBRARY" OR type STREQUAL "MODULE_LIBRARY")
      target_link_options(${t} PRIVATE -Wl,-z,undefs)
    endif()
  endforeach()
  get_property(subdirs DIRECTORY ${dir} PROPERTY SUBDIRECTORIES)
  foreach(d IN LISTS subdirs)
    _rbc_sanitize_allow_undefined(${d})
  endforeach()
endfunction()
function(_rbc_sanitize_finish)
  _rbc_sanitize_allow_undefined(${PROJECT_SOURCE_DIR})
endfunction()
if((RBC_SANITIZE OR RBC_FUZZ) AND CMAKE_C_COMPILER_ID MATCHES "Clang")
  cmake_language(DEFER DIRECTORY ${PROJECT_SOURCE_DIR} CALL _rbc_sanitize_finish)
endif()

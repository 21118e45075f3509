# CTest labels for every test (tests/README.md, "Labels"). Each tests/*/CMakeLists.txt
# (and bench/checks/CMakeLists.txt, label bench) ends with rbc_label_tests(FOLDER):
# every test of that directory gets the label FOLDER, then the labels below by name
# (appended: labels a test sets itself stay).
#
#   quick     our own code, seconds each: `ctest -L quick -j2` answers in under a
#             minute on 2 cores. Every test that is neither long nor external.
#   long      longer than about 5 s in the plain build (the paper's scenes, the
#             contact suite, the sweeps, the quick benches), or a test that needs
#             such a test's fixture
#   threads   tests whose point is the threaded solve (1 vs 2+ threads bitwise, the
#             thread contract, worlds on several threads): what the TSan build runs
#   valgrind  runs valgrind (excluded from the sanitizer builds: valgrind cannot run
#             an ASan/TSan binary)
#   browser   headless Chromium (RESOURCE_LOCK chromium), blender: Debian's Blender,
#   slurm     a one-node Slurm: each runs a third-party program on files our tests
#             wrote; excluded from the sanitizer builds (nothing of ours is
#             instrumented there beyond a PNG checker, and they add minutes)
#   fuzz      replays of the fuzz targets' seeds and regression inputs (tests/fuzz)
#   mono      Debian's Mono running a C# host of ours (tests/mono)
#   windows   the library cross-built with mingw-w64 and run under Debian's wine
#             (tests/windows)
#   xvfb      an X server in memory (Debian's xvfb-run) with Mesa's llvmpipe drawing
#             OpenGL: the real-time viewer (tests/glviewer)
#   external  browser, blender, slurm, mono, windows, xvfb and valgrind together
set(RBC_LABEL_LONG_REGEX
  "^(scene_funnel|scene_four_layers|scene_crumpled|scene_caches_thread_independent|abi_contact|abi_layer_order|core_clothcontact|import_sweep|bench_scenes_quick|bench_accuracy_quick|bench_stability_quick|cli_run_funnel|cli_batch_kill_trials|install_subdirectory|conformance_old_minor|conformance_catches_shared_state|conformance_catches_hangs)"
  CACHE INTERNAL "")
set(RBC_LABEL_THREADS_REGEX
  "^(core_rbgs|core_grid|core_clothcontact|abi_behaviour|abi_game_loop|abi_energy_guard|abi_target|abi_contact|abi_layer_order|abi_hardening|bench_scenes_quick|cli_batch)$"
  CACHE INTERNAL "")
set(RBC_LABEL_VALGRIND_REGEX "valgrind" CACHE INTERNAL "")
set(RBC_LABEL_BLENDER_REGEX "^(blender_|import_file_vertices_blender_live$)" CACHE INTERNAL "")
set(RBC_LABEL_SLURM_REGEX "^slurm_" CACHE INTERNAL "")
set(RBC_LABEL_MONO_REGEX "^mono_" CACHE INTERNAL "")
set(RBC_LABEL_WINDOWS_REGEX "^windows_" CACHE INTERNAL "")
set(RBC_LABEL_XVFB_REGEX "^glviewer_" CACHE INTERNAL "")

function(rbc_label_tests folder)
  get_property(tests DIRECTORY PROPERTY TESTS)
  foreach(t IN LISTS tests)
    set(labels ${folder})
    get_test_property(${t} RESOURCE_LOCK locks)
    set(external 0)
    if(locks MATCHES "chromium")
      list(APPEND labels browser)
      set(external 1)
    endif()
    foreach(kind VALGRIND BLENDER SLURM MONO WINDOWS XVFB)
      if(t MATCHES "${RBC_LABEL_${kind}_REGEX}")
        string(TOLOWER ${kind} l)
        list(APPEND labels ${l})
        set(external 1)
      endif()
    endforeach()
    if(external)
      list(APPEND labels external)
    endif()
    if(t MATCHES "${RBC_LABEL_THREADS_REGEX}")
      list(APPEND labels threads)
    endif()
    if(t MATCHES "${RBC_LABEL_LONG_REGEX}")
      list(APPEND labels long)
    elseif(NOT external)
      list(APPEND labels quick)
    endif()
    get_test_property(${t} LABELS have)
    if(have)
      list(APPEND labels ${have})
    endif()
    list(REMOVE_DUPLICATES labels)
    set_tests_properties(${t} PROPERTIES LABELS "${labels}")
  endforeach()
endfunction()

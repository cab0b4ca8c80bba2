# torqued_daemon_core: stages, fast replay, runtime threads, DDS publisher, systemd glue (owned by "daemon").
# Included from daemon/CMakeLists.txt; torqued_daemon (logging, config glue) and the torqued executable link it.
add_library(torqued_daemon_core STATIC
  ${CMAKE_CURRENT_LIST_DIR}/angle_chain.cpp
  ${CMAKE_CURRENT_LIST_DIR}/angle_stage.cpp
  ${CMAKE_CURRENT_LIST_DIR}/time_stage.cpp
  ${CMAKE_CURRENT_LIST_DIR}/fast_replay.cpp
  ${CMAKE_CURRENT_LIST_DIR}/replay_inputs.cpp
  ${CMAKE_CURRENT_LIST_DIR}/dds_publisher.cpp
  ${CMAKE_CURRENT_LIST_DIR}/rt_setup.cpp
  ${CMAKE_CURRENT_LIST_DIR}/runtime.cpp
  ${CMAKE_CURRENT_LIST_DIR}/state_store.cpp
)
target_include_directories(torqued_daemon_core PUBLIC ${CMAKE_CURRENT_LIST_DIR})
target_link_libraries(torqued_daemon_core PUBLIC torqued_io torqued_idl torqued_estimators Threads::Threads)
target_sources(torqued_daemon_core PRIVATE ${CMAKE_CURRENT_LIST_DIR}/stage_settings.cpp)
target_link_libraries(torqued_daemon_core PUBLIC torqued_config PkgConfig::SYSTEMD)
# The supervisor (config, logging, sd_notify) lives in torqued_daemon with logging.cpp.
target_sources(torqued_daemon PRIVATE ${CMAKE_CURRENT_LIST_DIR}/daemon_run.cpp ${CMAKE_CURRENT_LIST_DIR}/supervisor.cpp)
target_link_libraries(torqued_daemon PUBLIC torqued_daemon_core)

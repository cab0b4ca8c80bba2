# Mean-value engine (Crossley & Cook) and the Na et al. reproduction harness: library torqued_sim_mv.
# Kept apart from the crank-angle simulator (torqued_sim); included from tools/CMakeLists.txt.
add_library(torqued_sim_mv
  ${CMAKE_CURRENT_LIST_DIR}/mean_value_engine.cpp
  ${CMAKE_CURRENT_LIST_DIR}/na_repro.cpp
)
target_include_directories(torqued_sim_mv PUBLIC ${CMAKE_CURRENT_LIST_DIR})
target_link_libraries(torqued_sim_mv PUBLIC torqued_estimators)

# Install layout (used by the Debian package, debian/rules; `cmake --install build --prefix /usr` gives the same):
#   /usr/bin/torqued and the tools           /lib/systemd/system/torqued.service
#   /etc/torqued/torqued.yaml, cyclonedds.xml (conffiles: kept on upgrade when edited)
#   /usr/share/torqued/demo/                  the bundled demo recording the packaged configuration replays
#   /usr/share/torqued/demo/demo.yaml, truth_cycle.csv   its configuration and the simulator's truth (accuracy)
#   /usr/share/torqued/*.py                   plot scripts (the tools find them from their own location:
#                                             PREFIX/bin/TOOL -> PREFIX/share/torqued, tools/share_dir.hpp)
#   /usr/share/doc/torqued/README.md, docs/   the documentation; examples/: alert rules, Prometheus scrape job
#   /usr/bin/torque-dash, /usr/share/torqued/www/   the dashboard and its page
# No build or source directory is compiled into a binary (tests/tools/install_tree.sh checks the installed tree).
#   /usr/bin/torque-mcap-recover              rewrites an MCAP recording cut short (kill -9)
include(GNUInstallDirs)
install(TARGETS torqued torque-sim torque-echo torque-eval torque-decode torque-canreplay torque-latency
                torque-accuracy
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# Debian 12's dh_installsystemd looks for units in /lib/systemd/system (debian/rules sets it).
set(TORQUED_SYSTEMD_UNITDIR "lib/systemd/system" CACHE STRING "where torqued.service is installed")
install(FILES systemd/torqued.service DESTINATION ${TORQUED_SYSTEMD_UNITDIR})
install(FILES systemd/torqued.yaml systemd/cyclonedds.xml DESTINATION ${CMAKE_INSTALL_FULL_SYSCONFDIR}/torqued)
# The demo's configuration as installed: config/demo.yaml with its inputs next to it (../data/demo/ -> ./).
file(READ ${CMAKE_SOURCE_DIR}/config/demo.yaml _torqued_demo_yaml)
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${CMAKE_SOURCE_DIR}/config/demo.yaml)
string(REPLACE "../data/demo/" "" _torqued_demo_yaml "${_torqued_demo_yaml}")
file(WRITE ${CMAKE_BINARY_DIR}/share/torqued/demo/demo.yaml "${_torqued_demo_yaml}")
install(FILES data/demo/edges.csv data/demo/can.log data/demo/engine.yaml data/demo/truth_cycle.csv config/demo.dbc
              ${CMAKE_BINARY_DIR}/share/torqued/demo/demo.yaml
        DESTINATION ${CMAKE_INSTALL_DATADIR}/torqued/demo)
install(PROGRAMS tools/scripts/plot_torque.py tools/scripts/plot_latency.py tools/scripts/plot_decode.py
        DESTINATION ${CMAKE_INSTALL_DATADIR}/torqued)
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs)
if(TARGET torque-dash)  # the README names it; built when libcivetweb-dev and nlohmann-json3-dev are there
  install(TARGETS torque-dash torque-mcap-recover RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  install(FILES tools/dash/www/index.html tools/dash/www/dash.js tools/dash/www/dash.css
          DESTINATION ${CMAKE_INSTALL_DATADIR}/torqued/www)
endif()
install(FILES systemd/torqued-alerts.yml systemd/prometheus-torqued.yml
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)

# Install layout (used by the Debian package, debian/rules; `cmake --install build --prefix /usr` gives the same):
#   /usr/bin/torqued and the tools           /lib/systemd/system/torqued.service
#   /etc/torqued/torqued.yaml, cyclonedds.xml (conffiles: kept on upgrade when edited)
#   /usr/share/torqued/demo/                  the bundled demo recording the packaged configuration replays
#   /usr/share/torqued/*.py                   plot scripts (configure with -DTORQUED_SCRIPT_DIR=/usr/share/torqued)
#   /usr/share/doc/torqued/examples/          alert rules and a Prometheus scrape configuration
#   /usr/bin/torque-dash, /usr/share/torqued/www/   the dashboard and its page (-DTORQUED_DASH_WWW_DIR=...)
#   /usr/bin/torque-mcap-recover              rewrites an MCAP recording cut short (kill -9)
include(GNUInstallDirs)
install(TARGETS torqued torque-sim torque-echo torque-eval torque-decode torque-canreplay torque-latency
                torque-accuracy
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# Debian 12's dh_installsystemd looks for units in /lib/systemd/system (debian/rules sets it).
set(TORQUED_SYSTEMD_UNITDIR "lib/systemd/system" CACHE STRING "where torqued.service is installed")
install(FILES systemd/torqued.service DESTINATION ${TORQUED_SYSTEMD_UNITDIR})
install(FILES systemd/torqued.yaml systemd/cyclonedds.xml DESTINATION ${CMAKE_INSTALL_FULL_SYSCONFDIR}/torqued)
install(FILES data/demo/edges.csv data/demo/can.log data/demo/engine.yaml config/demo.dbc
        DESTINATION ${CMAKE_INSTALL_DATADIR}/torqued/demo)
install(PROGRAMS tools/scripts/plot_torque.py tools/scripts/plot_latency.py DESTINATION ${CMAKE_INSTALL_DATADIR}/torqued)
if(TARGET torque-dash)  # the README names it; built when libcivetweb-dev and nlohmann-json3-dev are there
  install(TARGETS torque-dash torque-mcap-recover RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  install(FILES tools/dash/www/index.html tools/dash/www/dash.js tools/dash/www/dash.css
          DESTINATION ${CMAKE_INSTALL_DATADIR}/torqued/www)
endif()
install(FILES systemd/torqued-alerts.yml systemd/prometheus-torqued.yml
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)

# The live view's page (web/) and uPlot (web/node_modules, installed by `make deps` with npm ci)
# compiled into the library as a C table (src/view/view_internal.h), regenerated when a file
# changes. Without node_modules the page still builds, with a stub that asks for `make deps`.
set(RTHS_WEB ${CMAKE_CURRENT_SOURCE_DIR}/web)
set(RTHS_UPLOT ${RTHS_WEB}/node_modules/uplot/dist)
set(RTHS_WEB_ASSETS ${RTHS_WEB}/index.html ${RTHS_WEB}/app.js ${RTHS_WEB}/app.css
  ${RTHS_WEB}/plots.js ${RTHS_WEB}/controller.html ${RTHS_WEB}/controller.js
  ${RTHS_WEB}/campaign.html ${RTHS_WEB}/campaign.js)
if(EXISTS ${RTHS_UPLOT}/uPlot.iife.min.js)
  list(APPEND RTHS_WEB_ASSETS ${RTHS_UPLOT}/uPlot.iife.min.js ${RTHS_UPLOT}/uPlot.min.css)
else()
  message(WARNING "web/node_modules is missing: `rths view` will ask for `make deps`")
  file(WRITE ${CMAKE_BINARY_DIR}/web-stub/uPlot.iife.min.js
    "window.rthsMissing = 'uPlot is not installed: run make deps, then rebuild';\n")
  file(WRITE ${CMAKE_BINARY_DIR}/web-stub/uPlot.min.css "")
  list(APPEND RTHS_WEB_ASSETS ${CMAKE_BINARY_DIR}/web-stub/uPlot.iife.min.js
    ${CMAKE_BINARY_DIR}/web-stub/uPlot.min.css)
endif()
string(REPLACE ";" "," RTHS_WEB_ASSET_LIST "${RTHS_WEB_ASSETS}")
add_custom_command(OUTPUT ${CMAKE_BINARY_DIR}/view_assets.c
  COMMAND ${CMAKE_COMMAND} -DOUT=${CMAKE_BINARY_DIR}/view_assets.c -DFILES=${RTHS_WEB_ASSET_LIST}
    -P ${RTHS_WEB}/embed.cmake
  DEPENDS ${RTHS_WEB_ASSETS} ${RTHS_WEB}/embed.cmake
  COMMENT "Embedding the live view's page and uPlot")
target_sources(rths_lib PRIVATE ${CMAKE_BINARY_DIR}/view_assets.c)

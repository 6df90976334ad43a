// The dashboard's page, script and stylesheet (coordinator/web/*), compiled into the coordinator
// by embed.cmake so that it serves them with no files beside it and no internet.
#pragma once

namespace lightfarm::web {

extern const char* const kIndexHtml;
extern const char* const kLoginHtml;
extern const char* const kAppJs;
extern const char* const kStyleCss;

}  // namespace lightfarm::web

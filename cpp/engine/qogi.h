// Umbrella header of the qogi C++ engine: `#include <engine/qogi.h>` after
// `find_package(qogi)` and linking `qogi::engine`.
#pragma once

#include "engine/optics/planck.h"
#include "engine/optics/spectral_response.h"
#include "engine/synth/gas.h"
#include "engine/synth/mean_flow.h"
#include "engine/synth/plume.h"
#include "engine/synth/release.h"
#include "engine/synth/truth.h"
#include "engine/synth/view.h"
#include "engine/util/check.h"
#include "engine/util/parallel.h"

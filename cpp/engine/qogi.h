// Umbrella header of the qogi C++ engine: `#include <engine/qogi.h>` after
// `find_package(qogi)` and linking `qogi::engine`.
#pragma once

#include "engine/optics/planck.h"
#include "engine/optics/spectral_response.h"
#include "engine/util/check.h"
#include "engine/util/parallel.h"
#include "engine/velocimetry/flow.h"
#include "engine/velocimetry/fluid_flow.h"
#include "engine/velocimetry/horn_schunck.h"
#include "engine/velocimetry/lucas_kanade.h"
#include "engine/velocimetry/opencv_flow.h"
#include "engine/velocimetry/piv.h"
#include "engine/velocimetry/postprocess.h"

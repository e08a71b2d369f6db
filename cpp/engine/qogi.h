// Umbrella header of the qogi C++ engine: `#include <engine/qogi.h>` after
// `find_package(qogi)` and linking `qogi::engine`.
#pragma once

#include "engine/io/jpegls.h"
#include "engine/optics/planck.h"
#include "engine/camera/camera.h"
#include "engine/optics/spectral_response.h"
#include "engine/inversion/inversion.h"
#include "engine/rte/binned_model.h"
#include "engine/rte/exact_model.h"
#include "engine/util/check.h"
#include "engine/util/parallel.h"

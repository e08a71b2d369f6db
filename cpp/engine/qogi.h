// Umbrella header of the qogi C++ engine: `#include <engine/qogi.h>` after
// `find_package(qogi)` and linking `qogi::engine`.
#pragma once

#include "engine/io/jpegls.h"
#include "engine/optics/planck.h"
#include "engine/camera/camera.h"
#include "engine/camera/calibration.h"
#include "engine/camera/noise.h"
#include "engine/camera/radiometric_table.h"
#include "engine/camera/warm_optics.h"
#include "engine/optics/spectral_response.h"
#include "engine/rte/binned_model.h"
#include "engine/rte/exact_model.h"
#include "engine/spectra/cross_section.h"
#include "engine/spectra/isotopologue.h"
#include "engine/spectra/line_list.h"
#include "engine/spectra/line_parameters.h"
#include "engine/spectra/voigt.h"
#include "engine/spectra/xsec_table.h"
#include "engine/util/check.h"
#include "engine/util/parallel.h"

#pragma once
#include "TestSupport/TestFields.h"  // moved; forwarding for Render/MacrocellGrid_test.cpp until it includes the new path

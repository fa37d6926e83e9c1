/* Forced in front of every file of test_assert (-include, see the Makefile):
 * CO_ASSERT reports to cmocka's mock_assert, so a test can expect a broken
 * internal contract to be caught. The default (the C assert) would abort. */
#ifndef TEST_ASSERT_HOOK_H
#define TEST_ASSERT_HOOK_H

void mock_assert(const int result, const char *const expression, const char *const file,
                 const int line);

#define CO_ASSERT(x) mock_assert((int)(x), #x, __FILE__, __LINE__)

#endif
